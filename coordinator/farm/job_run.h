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
#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "dispatch/dispatcher.h"
#include "farm/job_coherence.h"
#include "farm/job_cost.h"
#include "farm/verification.h"
#include "frame/frame_writer.h"
#include "jobs/job_store.h"
#include "planner/auto_guarded_planner.h"
#include "planner/planner.h"
#include "store/frame_store.h"

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

class JobRun {
 public:
  // Throws std::invalid_argument for options out of range (and SceneError, see
  // ResolveJobStrategy). `workers`: live workers now (auto sizes its segments by it).
  // pendingFrameBytes: memory for frames that finish ahead of their turn, beyond which
  // they wait on disk (PendingFrames).
  // jobMemoryBytes: the coordinator's memory for this job's frames (0: no limit); the
  // planner works on as many bins at once as fit in it.
  JobRun(const JobRecord& record, const FrameStore& store, const FrameWriterOptions& output = {}, int workers = 1,
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
  // How long one CollectFinishedFrames call may spend on frames.
  static constexpr std::chrono::milliseconds kFinishingTurn{20};

  bool OnPlannerResult(uint64_t taskId, const wire::Result& result);
  bool OnVerificationResult(uint64_t taskId, const wire::Result& result);
  // Records the frame, checks it, writes it and its masks, and feeds it to the coherence.
  void FinishFrame(JobStore& store, FinishedFrame frame);
  // Queues the mask for the absolute frame on the frame writer.
  void WriteMask(MaskKind kind, int absoluteFrame, std::vector<uint8_t> mask);
  // The bin width (segment length) the job runs with; 0 while auto's survey runs.
  int BinWidth() const;
  uint64_t PixelsPerFrame() const { return spec_.frameSize.Pixels(); }

  uint64_t id_;
  JobSpec spec_;
  ResolvedStrategy resolved_;
  PlannerOptions plannerOptions_;
  AutoGuardedPlanner* autoPlanner_ = nullptr;  // planner_, when auto surveys the bin width
  std::unique_ptr<Planner> planner_;
  PixelTally reported_;
  Verification verification_;
  FrameWriter writer_;
  std::deque<FinishedFrame> unwritten_;  // taken from the planner, not yet written
  JobCoherence coherence_;
  JobCost cost_;
  std::chrono::steady_clock::time_point started_;
  int framesDone_ = 0;
};

}  // namespace tcfarm
