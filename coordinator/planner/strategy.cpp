#include "coordinator/planner/strategy.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>

namespace tcfarm {

std::optional<Strategy> StrategyFromString(std::string_view name) {
  for (const StrategyNameEntry& entry : kStrategyNames) {
    if (entry.name == name) return entry.strategy;
  }
  return std::nullopt;
}

std::string_view StrategyName(Strategy strategy) {
  for (const StrategyNameEntry& entry : kStrategyNames) {
    if (entry.strategy == strategy) return entry.name;
  }
  return "unknown";
}

namespace {

// Brute force: the search with bins of 2, every pixel of every frame.
ResolvedStrategy Brute(std::string why) { return {Strategy::kBrute, 2, std::move(why), false, {}}; }

}  // namespace

ResolvedStrategy ResolveStrategy(Strategy requested, int binWidth, int frameCount, bool cameraOrLightsChange,
                                 int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices) {
  if (requested == Strategy::kBrute) return Brute("every pixel of every frame");
  if (requested != Strategy::kAuto) return {requested, binWidth, "as requested", false, {}};
  if (frameCount == 1) return Brute("one frame: nothing to reuse, every pixel traced");
  if (!cameraOrLightsChange) {
    const SegmentPlan plan = PlanSegments(frameCount, workers, pixelsPerFrame, prices);
    char why[256];
    if (plan.predictedRelativeCost >= kAutoBruteFromCost) {
      std::snprintf(why, sizeof why,
                    "camera and lights are static, but exact is predicted to cost %.3f of brute force's CPU "
                    "(at least %.2f): every pixel traced",
                    plan.predictedRelativeCost, kAutoBruteFromCost);
      return Brute(why);
    }
    std::snprintf(why, sizeof why,
                  "camera and lights are static: exact, %d segment%s of %d frames for %d worker%s (predicted "
                  "relative CPU cost %.3f, parallelism %.1f; frames spread over the workers)",
                  plan.segments, plan.segments == 1 ? "" : "s", plan.length, std::max(1, workers),
                  workers == 1 ? "" : "s", plan.predictedRelativeCost, plan.predictedParallelism);
    return {Strategy::kExact, plan.length, why, false, plan};
  }
  return {Strategy::kGuarded, std::clamp(frameCount, 2, kAutoWidestBin),
          "the camera or a light moves: guarded search, its bin width chosen by a coarse survey",
          /*surveyBinWidth=*/true, {}};
}

}  // namespace tcfarm
