// One job being rendered: its planner, its verification, its frame writer, and the
// figures it reports. Owned by the farm loop; not thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "dispatch/dispatcher.h"
#include "farm/pending_frames.h"
#include "farm/verification.h"
#include "frame/sequence_analysis.h"
#include "frame/frame_writer.h"
#include "jobs/job_store.h"
#include "planner/auto_guarded_planner.h"
#include "planner/planner.h"
#include "scene/scene.h"

namespace tcfarm {

// The strategy the job runs with: its request resolved (ResolveStrategy) against its
// scene's motion and `workers` live workers. An auto job stored before the store kept
// its motion (JobSpec::cameraOrLightsChange) has its scene parsed for it, which throws
// SceneError if the scene no longer parses.
ResolvedStrategy ResolveJobStrategy(const JobSpec& spec, int workers);
// With jobMemoryBytes > 0, as many live bins (segments) as fit in it (FramesHeldPerJob);
// throws std::invalid_argument naming the shortfall when not even one does.
PlannerOptions PlannerOptionsFor(const JobSpec& spec, const ResolvedStrategy& resolved,
                                 uint64_t jobMemoryBytes = 0);

// A task's tracing time: elapsed on the worker, and CPU time of its tracing threads. CPU
// time is what the job costs on a shared machine, where elapsed time also counts waiting
// for the cores.
struct TaskTime {
  double wall = 0;
  double cpu = 0;
  TaskTime& operator+=(const TaskTime& other) {
    wall += other.wall;
    cpu += other.cpu;
    return *this;
  }
  TaskTime operator-(const TaskTime& other) const { return {wall - other.wall, cpu - other.cpu}; }
};

class JobRun {
 public:
  // Throws std::invalid_argument for options out of range (and SceneError, see
  // ResolveJobStrategy). `workers`: live workers now (auto sizes its segments by it).
  // pendingFrameBytes: memory for frames that finish ahead of their turn, beyond which
  // they wait on disk (PendingFrames).
  // jobMemoryBytes: the coordinator's memory for this job's frames (0: no limit); the
  // planner works on as many bins at once as fit in it.
  JobRun(const JobRecord& record, const std::filesystem::path& storeRoot,
         const FrameWriterOptions& output = {}, int workers = 1,
         size_t pendingFrameBytes = kDefaultPendingFrameBytes, uint64_t jobMemoryBytes = 0);
  static constexpr size_t kDefaultPendingFrameBytes = size_t{256} << 20;

  uint64_t id() const { return id_; }
  FrameSize frameSize() const { return spec_.frameSize; }

  std::vector<DispatchTask> TakeTasks();
  // Feeds a result to the planner or the verification. False when it had it already.
  bool OnResult(uint64_t taskId, const wire::Result& result);
  // Hands finished frames to the writer and the verification, records them; returns how
  // many. Never waits for the writer: frames it has no room for wait for a later call.
  int CollectFinishedFrames(JobStore& store);
  bool Done() const {
    return planner_->Done() && !verification_.Pending() && unwritten_.empty() && writer_.Idle();
  }
  // Frames finished by the planner and not yet handed to the writer, beyond which the
  // job's tasks wait (kFarmFramesPerJob counts them).
  static constexpr size_t kMaxUnwrittenFrames = 4;
  // Waits for the frame writer; throws FrameIoError if a frame could not be written.
  void FinishWriting();

  // Progress and results so far, for the job record ("stats"). `final` adds the full
  // coherence analysis of the output sequence (pixel events, equation 3 per bin width).
  nlohmann::json Stats(bool final = false) const;
  uint64_t tracedPixels() const { return planner_->TracedPixels(); }
  uint64_t copiedPixels() const { return planner_->CopiedPixels(); }
  // Pixels traced and copied since the previous call: what the farm's counters lack.
  struct PixelTally {
    uint64_t traced = 0, copied = 0;
  };
  PixelTally TakeUnreportedPixels();

 private:
  // Task ids of verification requests carry this bit; planner ids never reach it.
  static constexpr uint64_t kVerificationTask = uint64_t{1} << 62;

  // Feeds frames in order to the coherence analysis and writes each one's change mask.
  void FinishFrame(JobStore& store, FinishedFrame frame);
  void TrackCoherence(int frame, const std::vector<float>& rgb);
  void AddToCoherence(Image frame);
  // Queues STORE/<job>/<kind>_NNNN.png for the absolute frame on the frame writer.
  void WriteMask(const char* kind, int absoluteFrame, std::vector<uint8_t> mask);
  nlohmann::json CostFigures() const;
  // The bin width (segment length) the job runs with; 0 while auto's survey runs.
  int BinWidth() const;

  uint64_t id_;
  JobSpec spec_;
  ResolvedStrategy resolved_;
  AutoGuardedPlanner* autoPlanner_ = nullptr;  // planner_, when auto surveys the bin width
  // How long one CollectFinishedFrames call may spend on frames.
  static constexpr std::chrono::milliseconds kFinishingTurn{20};
  PlannerOptions plannerOptions_;
  std::unique_ptr<Planner> planner_;
  PixelTally reported_;
  Verification verification_;
  FrameWriter writer_;
  std::deque<FinishedFrame> unwritten_;  // taken from the planner, not yet written
  std::chrono::steady_clock::time_point started_;
  TaskTime traceTime_;              // summed over tasks: the tracing time the job cost the farm
  TaskTime verifyTime_;             // of it, spent on verification
  bool cpuReported_ = true;         // every task's worker reported its CPU time
  std::map<int, TaskTime> frameTraceTime_;   // per unfinished frame, planner tasks only
  TaskTime fullFrameTime_;          // frames traced plainly in full: brute force's cost per frame
  int fullFrames_ = 0;
  std::set<int> framesWithHorizons_;  // unfinished frames some task traced with horizons
  TaskTime referenceTime_;          // reference frames: brute force itself
  uint64_t referencePixels_ = 0;
  uint64_t rays_[4] = {};          // primary, shadow, reflection, refraction
  uint64_t results_ = 0;
  int framesDone_ = 0;
  // Coherence needs frames in order; those that finish ahead of their turn wait here.
  SequenceAnalyzer coherence_;
  int nextCoherenceFrame_ = 0;
  PendingFrames waitingForCoherence_;
  // The last frame the coherence analysis took, for the next one's change mask.
  std::vector<float> previousRgb_;
};

}  // namespace tcfarm
