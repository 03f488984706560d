#include "coordinator/planner/job_memory.h"

#include <algorithm>
#include <cstdio>

#include "coordinator/planner/auto_guarded_planner.h"

namespace tcfarm {

JobMemoryShape RequestedJobShape(Strategy requested, int binWidth, int frameCount,
                                 std::optional<bool> cameraOrLightsChange, int width, int height,
                                 uint64_t pendingFrameBytes) {
  const ResolvedStrategy resolved =
      ResolveStrategy(requested, binWidth, frameCount, cameraOrLightsChange.value_or(true), /*workers=*/1,
                      uint64_t(width) * uint64_t(height));
  return {width, height, frameCount, resolved.strategy, resolved.binWidth, resolved.surveyBinWidth,
          pendingFrameBytes};
}

int FramesHeldPerJob(Strategy strategy, int binWidth, int liveBins, int frameCount) {
  const long width = strategy == Strategy::kBrute ? 2 : binWidth;
  const long planner = strategy == Strategy::kExact ? liveBins : liveBins * (width + 1);
  return static_cast<int>(std::min<long>(planner + kFarmFramesPerJob, long{frameCount} + 4));
}

uint64_t FrameBytes(int width, int height) { return uint64_t(width) * uint64_t(height) * 3 * sizeof(float); }

namespace {

// Frames ahead of their turn stay in memory while the next fits in the pending budget.
uint64_t PendingBytes(const JobMemoryShape& shape, uint64_t frameBytes) {
  const uint64_t frames = std::min<uint64_t>(shape.pendingFrameBytes / frameBytes, uint64_t(shape.frameCount));
  return frames * frameBytes;
}

// The survey's coarse samples: one per PlannerOptions::coarseTile square, float RGB, for
// each frame surveyed; the guarded planner takes them over.
uint64_t SurveyBytes(const JobMemoryShape& shape) {
  if (!shape.surveyBinWidth) return 0;
  constexpr uint64_t kTile = 8;  // PlannerOptions::coarseTile
  const uint64_t samples = ((uint64_t(shape.width) + kTile - 1) / kTile) * ((uint64_t(shape.height) + kTile - 1) / kTile);
  return samples * 3 * sizeof(float) * uint64_t(AutoGuardedPlanner::SurveyFrames(shape.frameCount, shape.binWidth));
}

}  // namespace

uint64_t JobMemoryBytes(const JobMemoryShape& shape, int liveBins) {
  const uint64_t frameBytes = std::max<uint64_t>(1, FrameBytes(shape.width, shape.height));
  const uint64_t held = frameBytes * uint64_t(FramesHeldPerJob(shape.strategy, shape.binWidth, liveBins, shape.frameCount));
  return held + PendingBytes(shape, frameBytes) + SurveyBytes(shape) +
         kBookkeepingBytesPerFrame * uint64_t(shape.frameCount);
}

int LiveBinsWithin(uint64_t budgetBytes, const JobMemoryShape& shape, int maxLiveBins) {
  for (int bins = maxLiveBins; bins >= 1; --bins) {
    if (JobMemoryBytes(shape, bins) <= budgetBytes) return bins;
  }
  return 0;
}

std::string MemoryText(uint64_t bytes) {
  char text[32];
  if (bytes < (uint64_t{1} << 20)) {
    std::snprintf(text, sizeof text, "%.1f KiB", static_cast<double>(bytes) / (1u << 10));
  } else if (bytes < (uint64_t{1} << 30)) {
    std::snprintf(text, sizeof text, "%.1f MiB", static_cast<double>(bytes) / (1u << 20));
  } else {
    std::snprintf(text, sizeof text, "%.2f GiB", static_cast<double>(bytes) / (1u << 30));
  }
  return text;
}

std::string MemoryShortfall(uint64_t budgetBytes, const JobMemoryShape& shape) {
  if (LiveBinsWithin(budgetBytes, shape, 1) > 0) return "";
  const uint64_t frameBytes = FrameBytes(shape.width, shape.height);
  const int frames = FramesHeldPerJob(shape.strategy, shape.binWidth, 1, shape.frameCount);
  return "a " + std::to_string(shape.width) + "x" + std::to_string(shape.height) + " frame takes " +
         MemoryText(frameBytes) + " as float RGB, and this job of " + std::to_string(shape.frameCount) +
         " frames holds up to " + std::to_string(frames) + " of them at once even one bin at a time: it needs " +
         MemoryText(JobMemoryBytes(shape, 1)) + " with its other state; the farm has " + MemoryText(budgetBytes) +
         " for all its running jobs (--farm-memory)";
}

}  // namespace tcfarm
