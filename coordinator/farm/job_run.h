// One job being rendered: it passes tasks from its planner and its verification to the
// farm, results back to them, and finished frames on to the frame writer and the
// coherence analysis; it reports the figures of all of these. Each part lives in its own
// class (Planner, Verification, FrameWriter, JobCoherence, JobCost), to be read and
// tested alone. Owned by the farm loop; not thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/dispatch/dispatcher.h"
#include "coordinator/farm/exactness_audit.h"
#include "coordinator/farm/frame_records.h"
#include "coordinator/farm/job_coherence.h"
#include "coordinator/farm/referee_sample.h"
#include "coordinator/farm/job_cost.h"
#include "coordinator/farm/verification.h"
#include "proto/frame/frame_writer.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/planner/auto_guarded_planner.h"
#include "coordinator/planner/job_memory.h"
#include "coordinator/planner/planner.h"
#include "coordinator/store/frame_finisher.h"
#include "coordinator/store/frame_store.h"

namespace tcfarm {

// The strategy the job runs with: its request resolved (ResolveStrategy) against its
// scene's motion and `workers` live workers. An auto job stored before the store kept
// its motion (JobSpec::cameraOrLightsChange) has its scene parsed for it, which throws
// SceneError if the scene no longer parses.
ResolvedStrategy ResolveJobStrategy(const JobSpec& spec, int workers, const SegmentPrices& prices = {});
// With jobMemoryBytes > 0, as many live bins (segments) as fit in it (LiveBinsWithin);
// throws std::invalid_argument naming the shortfall when not even one does.
PlannerOptions PlannerOptionsFor(const JobSpec& spec, const ResolvedStrategy& resolved, uint64_t jobMemoryBytes = 0,
                                 uint64_t pendingFrameBytes = 0);

// A plan (JobRecord::plan) as the job store keeps it, and back; nullopt for an empty plan.
// Throws std::invalid_argument for a plan naming no strategy this coordinator knows.
nlohmann::json PlanJson(const ResolvedStrategy& resolved);
std::optional<ResolvedStrategy> PlanFromJson(const nlohmann::json& plan);

// What a resumed job already has: frames recorded in the job store whose files are in the
// frame store. A recorded frame whose files are gone is `missing`: its record is dropped.
struct KeptFrames {
  std::vector<bool> kept;    // index = frame - firstFrame
  int count = 0;
  uint64_t traced = 0, copied = 0;  // their pixels, as recorded
  std::vector<int> missing;  // absolute frame numbers
};
KeptFrames FindKeptFrames(const JobRecord& record, const FrameStore& store, const FrameWriterOptions& output);

// What the farm gives every job it runs.
struct JobRunSettings {
  FrameWriterOptions output;  // how the frame store writes the job's frames
  int workers = 1;            // live now: auto cuts exact's segments for them
  // Memory for frames that finish ahead of their turn, beyond which they wait on disk
  // (PendingFrames).
  static constexpr size_t kDefaultPendingFrameBytes = size_t{256} << 20;
  size_t pendingFrameBytes = kDefaultPendingFrameBytes;
  // The coordinator's memory the farm gave this job (0: no limit): the planner works on as
  // many bins at once as fit in it (LiveBinsWithin).
  uint64_t jobMemoryBytes = 0;
  // Settles the disputes of a job that promises exactness (ExactnessAudit); none leaves
  // them unsettled.
  Referee* referee = nullptr;
  SegmentPrices segmentPrices;  // the scene's, or its kind's, as measured (PriceBook): auto's model
};

class JobRun {
 public:
  // Throws std::invalid_argument for options out of range (and SceneError, see
  // ResolveJobStrategy).
  JobRun(const JobRecord& record, const FrameStore& store, const JobRunSettings& settings = {});

  uint64_t id() const { return id_; }
  // What the farm gave the job (JobRunSettings::jobMemoryBytes), held until the run ends.
  uint64_t memoryGranted() const { return memoryGranted_; }
  FrameSize frameSize() const { return spec_.frameSize; }
  // The job's request, without its scene text (the dispatcher holds that).
  const JobSpec& spec() const { return spec_; }
  int firstFrame() const { return spec_.firstFrame; }
  int lastFrame() const { return spec_.lastFrame; }
  // How the job's previews show its frames (its submission's view).
  ViewTransform previewView() const { return JobPreviewView(spec_); }

  // workers: live now; the planner spreads each trace request over them.
  std::vector<DispatchTask> TakeTasks(int workers = 1);
  // Feeds a result to the planner, the verification or a repair. False when it had it
  // already. worker: who traced it (a principal, or Referee::kName); checks of a frame
  // then go to someone else, and a worker found returning wrong values is traced back
  // through it. onProbation: the worker joined lately, so the referee samples more of its
  // values.
  bool OnResult(const DispatchTask& task, const wire::Result& result, const std::string& worker,
                bool onProbation = false);
  // A check or repair of this job that no connected worker may trace (the dispatcher's
  // TakeStranded): the referee traces it, and its answer comes back as a result by
  // Referee::kName. Throws std::runtime_error when the job has no referee.
  void TraceByReferee(DispatchTask task, const JobStore& store);
  // Workers this job's disputes and unseen sample showed returning wrong values, since the
  // last call. The farm distrusts them and tells every job (OnWorkerDistrusted); a job is
  // not done while it holds any.
  std::vector<ExactnessAudit::Verdict> TakeVerdicts();
  // A worker found returning wrong values: frames its values reached are traced again
  // and rewritten where they differ. name: how the job record names it.
  void OnWorkerDistrusted(const std::string& worker, const std::string& name);
  // Hands finished frames to the writer and the verification, and records in the job
  // store the frames the writer has put in place (a frame is recorded only once its files
  // are there); returns how many frames it handed on. Never waits for the writer: frames
  // it has no room for wait for a later call. A job store that refuses the records (disk
  // full) leaves them owed, to be retried by the next call. Throws FrameIoError naming
  // the first frame that could not be written, once what was written is recorded.
  int CollectFinishedFrames(JobStore& store);
  bool Done() const {
    return planner_->Done() && !verification_.Pending() && !audit_.Pending() && !sample_.Pending() &&
           refereeChecks_.empty() && forReferee_.empty() && verdicts_.empty() && toReverify_.empty() &&
           unwritten_.empty() && writer_.Idle() && !records_.AnyWriting() && !RecordsOwed();
  }
  // Records what the writer has put in place since the last call, and what is owed from
  // before (the plan, frames to forget); false, keeping them owed, while the job store
  // refuses writes (RecordsBlocked says why). Other job store errors throw.
  bool RecordWrittenFrames(JobStore& store);
  bool RecordsOwed() const { return records_.Owed(); }
  const std::string& RecordsBlocked() const { return records_.blocked(); }
  // Which frame (or mask) could not be written first and why, with how many frames are
  // written and recorded; nullopt when every write succeeded.
  std::optional<std::string> WriteFailure() const;
  // Frames finished by the planner and not yet handed to the writer, beyond which the
  // job's tasks wait (kFarmFramesPerJob counts them).
  static constexpr size_t kMaxUnwrittenFrames = 4;
  // Waits for the frame writer; throws FrameIoError if a frame could not be written.
  void FinishWriting();

  // The frames the job is working on (the scene's numbers, ascending): planner tasks out
  // for them, or finished and not yet in the store.
  std::vector<int> TracingFrames() const;

  // Progress and results so far, for the job record ("stats"). `final` adds the full
  // coherence analysis of the output sequence (pixel events, equation 3 per bin width).
  nlohmann::json Stats(bool final = false) const;
  uint64_t tracedPixels() const { return planner_->TracedPixels(); }
  // An exact job's segment prices as it measured them (auto's model for the next job).
  std::optional<SegmentPrices> MeasuredSegmentPrices() const { return cost_.MeasuredSegmentPrices(); }
  uint64_t copiedPixels() const { return planner_->CopiedPixels(); }
  // Pixels traced and copied since the previous call: what the farm's counters lack.
  struct PixelTally {
    uint64_t traced = 0, copied = 0;
  };
  PixelTally TakeUnreportedPixels();

 private:
  // Task ids of verification requests and of repairs carry these bits; planner ids stay
  // below them (kPlannerTaskIdBits). A repair's id is the bit and its frame.
  static constexpr uint64_t kVerificationTask = uint64_t{1} << 62;
  static constexpr uint64_t kRepairTask = uint64_t{1} << 63;
  static_assert(kPlannerTaskIdBits <= 62, "planner task ids must not reach the farm's bits");
  // How long one CollectFinishedFrames call may spend on frames.
  static constexpr std::chrono::milliseconds kFinishingTurn{20};
  // Buffers of written frames kept for the next ones: a frame is written for each one
  // finished, so two cover the writer's threads handing them back at once.
  static constexpr size_t kRecycledFrameBuffers = 2;

  // OnResult's work before the sample: to the planner, the verification or a repair.
  bool Accept(const DispatchTask& task, const wire::Result& result, const std::string& worker);
  bool OnPlannerResult(const DispatchTask& task, const wire::Result& result, const std::string& worker);
  // The referee's answers to checks it traced, fed back as results. Throws
  // std::runtime_error for a check it could not trace: the job cannot keep its promise.
  void HearRefereeChecks();
  // The job's scene, read from the job store once (the run does not keep it otherwise).
  const std::string& SceneJson(const JobStore& store);
  // The frames after a traced one into which the job may copy its values.
  int CopyReach(int window) const;
  bool OnVerificationResult(uint64_t taskId, const wire::Result& result, const std::string& worker);
  // A frame traced again in full: rewritten where it differs from what was written.
  bool OnRepairResult(const DispatchTask& task, const wire::Result& result, const std::string& worker);
  uint64_t PixelsDifferingFromWritten(int absoluteFrame, const std::vector<float>& rgb) const;
  // Frames whose reference a distrusted worker traced, read back once written and compared
  // with a reference traced again.
  void ReverifyWrittenFrames();
  // Disputes and the unseen sample to the referee, its verdicts back.
  void Audit(const JobStore& store);
  // Checks the frame, writes it and its masks, and feeds it to the coherence.
  void FinishFrame(FinishedFrame frame);
  // Kept frames whose turn in the coherence analysis has come, read back from the store,
  // as far as the turn allows.
  void FeedKeptFrames(std::chrono::steady_clock::time_point turnEnds);
  // Queues the mask for the absolute frame on the frame writer.
  void WriteMask(MaskKind kind, int absoluteFrame, std::vector<uint8_t> mask);
  // The bin width (segment length) the job runs with; 0 while auto's survey runs.
  int BinWidth() const;
  // The plan once auto's survey chose guarded's width (or brute force's bins of 2): its
  // prediction, and the reason saying so.
  ResolvedStrategy SurveyedPlan() const;
  // stats.strategy: the plan, its one prediction and what auto weighed.
  nlohmann::json StrategyStats() const;
  uint64_t PixelsPerFrame() const { return spec_.frameSize.Pixels(); }

  // Declared first, so destroyed last: once the job's frames are freed, the pages glibc
  // keeps in its arenas go back to the system (malloc_trim), so the coordinator's RSS
  // falls back when a job ends or is canceled.
  struct ReturnsFreedMemory {
    ReturnsFreedMemory() = default;
    ReturnsFreedMemory(const ReturnsFreedMemory&) = delete;
    ReturnsFreedMemory& operator=(const ReturnsFreedMemory&) = delete;
    ~ReturnsFreedMemory();
  } returnsFreedMemory_;
  uint64_t id_;
  uint64_t memoryGranted_;
  JobSpec spec_;
  FrameStore frameStore_;
  KeptFrames kept_;  // from before a restart; nothing for a new job
  ResolvedStrategy resolved_;
  // Pixel buffers of written frames, for exact's next finished frames; none for the other
  // strategies.
  std::shared_ptr<FrameBufferPool> frameBuffers_;
  PlannerOptions plannerOptions_;
  AutoGuardedPlanner* autoPlanner_ = nullptr;  // planner_, when auto surveys the bin width
  std::unique_ptr<Planner> planner_;
  PixelTally reported_;
  Verification verification_;
  ExactnessAudit audit_;
  RefereeSample sample_;  // the referee's unseen check of every worker's values
  Referee* referee_;
  std::map<uint64_t, DispatchTask> refereeChecks_;  // out with the referee, by question id
  uint64_t nextRefereeCheck_ = 1;
  std::vector<DispatchTask> forReferee_;  // spot checks, for the referee at the next Audit
  std::set<int> toReverify_;  // frames whose reference a distrusted worker traced, once written
  std::string sceneJson_;          // read once, when the referee first needs it
  std::vector<ExactnessAudit::Verdict> verdicts_;
  // Planner tasks in flight: their chain and step (TraceTask), for the job's span.
  std::unordered_map<uint64_t, std::pair<int, int>> taskChains_;
  std::map<int, int> tasksOut_;  // planner tasks handed out and not answered, by absolute frame
  // By frame (the job's): whether its files are written, so a repair may replace them.
  std::vector<bool> written_;
  FrameWriter writer_;
  std::deque<FinishedFrame> unwritten_;  // taken from the planner, not yet written
  JobCoherence coherence_;
  JobCost cost_;
  std::chrono::steady_clock::time_point started_;
  int framesDone_ = 0;  // handed to the writer by this run

  FrameRecords records_;               // the job store's view, kept in step with the files
  bool chosenWidthPlanned_ = false;  // auto's survey result is in the plan
  // Kept frames the planner produced again (bins or segments that were in progress).
  uint64_t retracedPixels_ = 0;
  int retracedFrames_ = 0;
};

}  // namespace tcfarm
