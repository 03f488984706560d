#include "coordinator/planner/planner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "coordinator/planner/exact_planner.h"
#include "coordinator/planner/guarded_planner.h"
#include "coordinator/planner/search_planner.h"

namespace tcfarm {

std::unique_ptr<Planner> MakePlanner(Strategy strategy, const PlannerOptions& options) {
  switch (strategy) {
    case Strategy::kBrute: {
      PlannerOptions everyFrame = options;
      everyFrame.binWidth = 2;  // bins of two frames trace both, so nothing is ever copied
      return std::make_unique<SearchPlanner>(everyFrame);
    }
    case Strategy::kSearch:
      return std::make_unique<SearchPlanner>(options);
    case Strategy::kGuarded:
      return std::make_unique<GuardedPlanner>(options);
    case Strategy::kExact:
      return std::make_unique<ExactPlanner>(options);
    case Strategy::kAuto:
      break;
  }
  throw std::invalid_argument("no planner for strategy '" + std::string(StrategyName(strategy)) +
                              "'; expected a resolved strategy (ResolveStrategy)");
}

namespace planner_internal {

std::vector<PixelSet> SplitForWorkers(const PixelSet& pixels, const PlannerOptions& options) {
  const uint64_t workers = static_cast<uint64_t>(std::max(1, options.workers));
  const uint64_t share = (pixels.size() + workers - 1) / workers;
  const uint64_t floor = std::min<uint64_t>(PlannerOptions::kMinTaskPixels, options.maxTaskPixels);
  return pixels.Split(static_cast<uint32_t>(std::clamp<uint64_t>(share, floor, options.maxTaskPixels)));
}

bool AllKept(const PlannerOptions& options, int first, int last) {
  for (int frame = first; frame <= last; ++frame) {
    if (static_cast<size_t>(frame) >= options.keptFrames.size() || !options.keptFrames[frame]) return false;
  }
  return true;
}

std::vector<std::pair<int, int>> TileBins(int frameCount, int binWidth) {
  if (frameCount == 1) return {{0, 0}};
  std::vector<std::pair<int, int>> bins;
  const long long step = binWidth - 1;
  for (long long left = 0; left < frameCount - 1; left += step) {
    bins.emplace_back(static_cast<int>(left), static_cast<int>(std::min<long long>(left + step, frameCount - 1)));
  }
  return bins;
}

void FailCheck(const char* planner, const std::string& what) {
  throw std::logic_error(std::string(planner) + " invariant broken: " + what);
}

void Check(bool condition, const char* planner, const std::string& what) {
  if (!condition) FailCheck(planner, what);
}

void RequireOption(bool valid, const char* name, long long value, const char* expected) {
  if (valid) return;
  throw std::invalid_argument(std::string("PlannerOptions.") + name + " is " + std::to_string(value) +
                              "; expected " + expected);
}

void ValidateCommonOptions(const PlannerOptions& options) {
  RequireOption(options.width >= 1, "width", options.width, ">= 1");
  RequireOption(options.height >= 1, "height", options.height, ">= 1");
  const long long pixels = static_cast<long long>(options.width) * options.height;
  // Pixel indices are uint32_t, and a span's end must fit as well.
  RequireOption(pixels <= static_cast<long long>(UINT32_MAX), "width * height", pixels, "<= 4294967295");
  RequireOption(options.frameCount >= 1, "frameCount", options.frameCount, ">= 1");
  RequireOption(options.maxTaskPixels >= 1, "maxTaskPixels", options.maxTaskPixels, ">= 1");
  RequireOption(options.maxLiveBins >= 1, "maxLiveBins", options.maxLiveBins, ">= 1");
  if (!(std::isfinite(options.tolerance) && options.tolerance >= 0)) {
    throw std::invalid_argument("PlannerOptions.tolerance is " + std::to_string(options.tolerance) +
                                "; expected a finite value >= 0");
  }
}

namespace {

std::string ResultName(uint64_t taskId, int frame) {
  return "result of task " + std::to_string(taskId) + " (frame " + std::to_string(frame) + ")";
}

}  // namespace

void ValidateRgb(uint64_t taskId, int frame, uint64_t pixels, const float* rgb, size_t floatCount) {
  const uint64_t expected = pixels * 3;
  if (floatCount != expected) {
    throw std::invalid_argument(ResultName(taskId, frame) + " has " + std::to_string(floatCount) +
                                " floats; expected " + std::to_string(expected) + " (3 per pixel, " +
                                std::to_string(pixels) + " pixels)");
  }
  if (rgb == nullptr && floatCount > 0) throw std::invalid_argument(ResultName(taskId, frame) + " has no data");
  for (size_t i = 0; i < floatCount; ++i) {
    if (!std::isfinite(rgb[i])) {
      throw std::invalid_argument(ResultName(taskId, frame) + " has a non-finite value at float " +
                                  std::to_string(i) + "; expected finite RGB");
    }
  }
}

void ValidateHorizons(uint64_t taskId, int frame, int window, uint64_t pixels, const int32_t* horizons,
                      size_t horizonCount) {
  if (horizonCount != pixels || (horizons == nullptr && pixels > 0)) {
    throw std::invalid_argument(ResultName(taskId, frame) + " has " +
                                std::to_string(horizons == nullptr ? 0 : horizonCount) + " horizons; expected " +
                                std::to_string(pixels) + " (one per pixel, window " + std::to_string(window) + ")");
  }
  // 64-bit so that a job's last frames cannot overflow the bound.
  const long long lowest = static_cast<long long>(frame) + 1;
  const long long highest = static_cast<long long>(frame) + window + 1;
  for (size_t i = 0; i < horizonCount; ++i) {
    if (horizons[i] < lowest || horizons[i] > highest) {
      throw std::invalid_argument(ResultName(taskId, frame) + " has horizon " + std::to_string(horizons[i]) +
                                  " at pixel " + std::to_string(i) + "; expected " + std::to_string(lowest) +
                                  " .. " + std::to_string(highest));
    }
  }
}

}  // namespace planner_internal
}  // namespace tcfarm
