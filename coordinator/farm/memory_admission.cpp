#include "coordinator/farm/memory_admission.h"

#include <algorithm>

#include "coordinator/planner/job_memory.h"
#include "coordinator/planner/planner.h"

namespace tcfarm {

bool MemoryAdmission::Admits(const JobRecord& job, uint64_t used, uint64_t* granted, bool* passable) {
  if (budget_.farmMemoryBytes == 0) return true;
  const uint64_t left = budget_.farmMemoryBytes - std::min(used, budget_.farmMemoryBytes);
  const JobMemoryShape shape =
      RequestedJobShape(job.spec.strategy, job.spec.binWidth, job.FrameCount(), job.spec.cameraOrLightsChange,
                        job.spec.frameSize.width, job.spec.frameSize.height, budget_.pendingFrameBytes);
  if (const int bins = LiveBinsWithin(left, shape, PlannerOptions{}.maxLiveBins); bins > 0) {
    *granted = JobMemoryBytes(shape, bins);
    return true;
  }
  // Never fits, even alone (queued before the farm's memory shrank): it starts and fails
  // with the shortfall rather than waiting forever and, past longestWait, holding every
  // job behind it.
  if (LiveBinsWithin(budget_.farmMemoryBytes, shape, 1) == 0) {
    *granted = budget_.farmMemoryBytes;
    return true;
  }
  const auto known = waiting_.find(job.id);
  const SteadyTime since = known != waiting_.end() ? known->second : clock_.Now();
  waitingNow_.emplace(job.id, since);
  *passable = clock_.Now() - since < budget_.longestWait;
  return false;
}

}  // namespace tcfarm
