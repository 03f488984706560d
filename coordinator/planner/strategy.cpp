#include "planner/strategy.h"

#include <algorithm>

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

ResolvedStrategy ResolveStrategy(Strategy requested, int binWidth, int frameCount,
                                 bool cameraOrLightsChange, int workers) {
  if (requested == Strategy::kBrute) return {Strategy::kBrute, 2, "every pixel of every frame"};
  if (requested != Strategy::kAuto) return {requested, binWidth, "as requested"};
  if (!cameraOrLightsChange) {
    // Each segment costs one full frame; one segment per worker keeps all of them busy.
    const int segments = std::clamp(workers, 1, frameCount);
    const int length = (frameCount + segments - 1) / segments;
    return {Strategy::kExact, std::max(1, length),
            "camera and lights are static: exact, one segment per worker"};
  }
  return {Strategy::kGuarded, std::clamp(frameCount, 2, kAutoWidestBin),
          "the camera or a light moves: guarded search, its bin width chosen by a coarse survey",
          /*surveyBinWidth=*/true};
}

}  // namespace tcfarm
