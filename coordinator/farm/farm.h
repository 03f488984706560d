// The farm loop: claims jobs from the job store, runs their planners, hands tasks to the
// dispatcher, feeds results back, writes finished frames, and finishes jobs.
//
// One thread runs the loop and owns everything in it. Other threads (the HTTP server)
// talk to it only through the job store, RequestCancel, and Snapshot.
//
// The job store may refuse writes (its disk full): the loop never stops for that. A job
// whose frames or final state cannot be recorded stays in memory, its frames on disk,
// and the records are retried every claim interval until the store takes them; then the
// job completes (or fails) as it would have. Nothing is lost, nothing recorded twice.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "coordinator/dispatch/dispatcher.h"
#include "coordinator/farm/farm_control.h"
#include "coordinator/farm/farm_metrics.h"
#include "coordinator/farm/farm_requests.h"
#include "coordinator/farm/job_run.h"
#include "coordinator/farm/memory_admission.h"
#include "coordinator/farm/price_book.h"
#include "coordinator/farm/referee.h"
#include "coordinator/store/frame_finisher.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/asset_store.h"

namespace tcfarm {

struct FarmOptions {
  // Loopback unless keys are given: an unauthenticated socket must not face a network.
  std::string endpoint = "tcp://127.0.0.1:5555";
  // The coordinator's CURVE secret key and the workers' allow-list; none: no authentication.
  std::optional<CurveServerKeys> curve;
  std::filesystem::path storeRoot = "store";
  // Jobs rendered at once; more queue in the store. Several keep the workers busy while
  // one job's search waits on its last results.
  int maxRunningJobs = 4;
  HeartbeatPolicy heartbeat;
  // How the frame store keeps each job's frames. While a job renders they are written
  // uncompressed and without previews, and finished to this once no job renders
  // (FrameFinisher).
  FrameWriterOptions output;
  // Per job: memory for frames that finish ahead of their turn; beyond it they wait on disk.
  size_t pendingFrameBytes = JobRunSettings::kDefaultPendingFrameBytes;
  // The coordinator's memory for all running jobs together (0: no limit): their working
  // frames, pending frames, plans and bookkeeping (JobMemoryBytes). A job is claimed once
  // its need, estimated from its request, fits in what the running jobs leave; until then
  // it stays queued, and jobs behind it that fit may pass it (see ClaimJobs).
  uint64_t farmMemoryBytes = 0;
  // A job that waited for memory this long is passed by no later job: the memory drains
  // to it as running jobs end.
  Milliseconds longestMemoryWait{5 * 60 * 1000};
  // Who settles disputes and traces the checks no worker may; none: the farm's own
  // TracingReferee. Tests whose workers trace nothing give one that knows their values.
  Referee* referee = nullptr;
  // The coordinator's one budget for importing scenes, which the farm's own referee shares
  // with the API's scene checks and submits; none: the referee's scenes are not counted.
  std::shared_ptr<ImportBudget> importBudget;
};

class Farm : public FarmControl, private DispatchSink {
 public:
  Farm(JobStore& store, FarmOptions options, const Clock& clock);
  ~Farm() override;

  std::string BoundEndpoint() const { return dispatcher_.BoundEndpoint(); }
  // The CURVE public key workers need (Z85), or "" without CURVE.
  const std::string& PublicKey() const { return dispatcher_.PublicKey(); }
  FarmMetrics& metrics() { return metrics_; }

  // Runs the loop until *stop, calling afterStep (if any) after each step; then tells the
  // workers goodbye, so they reconnect at once instead of after their coordinator
  // timeout. Jobs still running stay "running" in the store and are requeued by the next
  // coordinator (RequeueInterrupted).
  void Run(const std::atomic<bool>& stop, const std::function<void()>& afterStep = {});
  // One iteration; tests drive the loop with this.
  void Step(Milliseconds pollTimeout);

  // Thread-safe.
  void RequestCancel(uint64_t jobId) override;
  void RequestPriority(uint64_t jobId, int priority) override;
  bool ReleaseJob(uint64_t jobId) override;
  FarmSnapshot Snapshot() const override;
  std::vector<WorkerBan> Bans() const override { return bans_.List(); }
  bool LiftBan(const std::string& principal) override;

 private:
  void OnResult(const DispatchTask& task, wire::Result&& result, double latencySeconds,
                const WorkerState& worker) override;
  void OnTaskFailed(uint64_t jobId, uint64_t plannerTaskId, const std::string& why) override;

  void ClaimJobs();
  // Memory the running jobs were given (JobRun::memoryGranted).
  uint64_t MemoryGranted() const;
  // granted: the job's share of the farm's memory (0: no limit).
  void StartJob(const JobRecord& record, uint64_t granted = 0);
  // What other threads asked for: cancels, priority changes, jobs to let go of. Before
  // claims, so that a job canceled and retried at once is stopped before it is claimed again.
  void ApplyRequests();
  // Stops a job's run (canceled, or about to be deleted): its tasks are dropped, frames
  // already finished are written, and the frame finisher gets them.
  void StopRun(uint64_t jobId);
  // Worker losses and frame events, into the job store's event log.
  void RecordEvents();
  void PumpTasks();
  void CollectFrames();
  // Workers the jobs' referee verdicts found returning wrong values: banned (by key, in
  // the store), and every running job repairs the frames their values reached.
  void DistrustWrongWorkers();
  // Checks and repairs no connected worker may trace go to the referee.
  void RouteStrandedChecks();
  void FinishJob(uint64_t jobId);
  void FailJob(uint64_t jobId, const std::string& why);
  // A job done rendering (completed, or failed with `why`) whose records are still owed.
  struct ClosingJob {
    std::unique_ptr<JobRun> run;  // null for a job that never started
    bool failed = false;
    std::string why;
    nlohmann::json stats;
    std::vector<EventDraft> events;  // recorded with the completion (the verification's)
  };
  void Close(uint64_t jobId, ClosingJob closing);
  void SettleClosingJobs();
  // Records the job's last frames and its final state; false while the store refuses.
  bool Settle(uint64_t jobId, ClosingJob& closing);
  void NoteRefusedWrite(const std::exception& error);
  void CountError(const nlohmann::json& error);
  void UpdateMetrics();
  void PublishSnapshot();

  JobStore& store_;
  FarmOptions options_;
  const Clock& clock_;
  FrameStore frameStore_;  // where options_.storeRoot holds each job's files
  // The store's assets, which workers fetch by hash (dispatcher_ reads them).
  class StoredAssets : public AssetSource {
   public:
    explicit StoredAssets(const std::filesystem::path& root) : store_(root) {}
    std::optional<uint64_t> SizeOf(const std::string& hash) const override { return store_.SizeOf(hash); }
    std::string ReadPiece(const std::string& hash, uint64_t offset, size_t maxBytes) const override {
      return store_.ReadPiece(hash, offset, maxBytes);
    }

   private:
    AssetStore store_;
  };
  StoredAssets assets_;
  FarmMetrics metrics_;
  Dispatcher dispatcher_;
  std::unique_ptr<TracingReferee> ownReferee_;  // unless the options name a referee
  Referee* referee_;  // settles disputes, traces the checks no worker may
  WorkerBans bans_;         // applied to the dispatcher at start
  PriceBook prices_;  // segment prices exact jobs measured, per scene (auto's model)
  // Prices from the store (a previous coordinator's measurements) into prices_; the
  // measurement of a finished exact job into both.
  void LoadScenePrices();
  void KeepScenePrices(const JobRun& run);
  FrameFinisher finisher_;       // compresses and previews jobs' frames when no job renders
  // Jobs a previous coordinator left unfinished (FrameFinisher) go back to the finisher.
  void RequeueUnfinishedFrames();
  int LiveWorkers() const { return static_cast<int>(dispatcher_.registry().workers().size()); }
  std::map<uint64_t, std::unique_ptr<JobRun>> runs_;
  std::map<uint64_t, ClosingJob> closing_;
  bool interruptedRequeued_ = false;  // RequeueInterrupted went through (before any claim)
  MemoryAdmission admission_;  // which queued jobs the farm's memory admits
  SteadyTime lastRefusalLogged_{};
  DispatcherCounters lastCounters_;
  uint64_t finishedTraced_ = 0, finishedPixels_ = 0;
  SteadyTime lastClaim_{}, lastSnapshot_{}, lastFrameEvents_{};

  FarmRequests requests_;  // what other threads ask of the loop, and its snapshot for them
};

}  // namespace tcfarm
