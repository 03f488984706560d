// What the planners' tests share: options for small frames, the fake tracer that answers
// a task from a synthetic animation, and the check of finished frames against it.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <vector>

#include "coordinator/planner/planner.h"

namespace tcfarm::planner_test {

using Rgb = std::array<float, 3>;
// The fake tracer: a synthetic animation, the value of pixel (x, y) at a frame.
using Animation = std::function<Rgb(int frame, int x, int y)>;

inline PlannerOptions Options(int width, int height, int frameCount, int binWidth,
                              int coarseTile = 8) {
  PlannerOptions options;
  options.width = width;
  options.height = height;
  options.frameCount = frameCount;
  options.binWidth = binWidth;
  options.coarseTile = coarseTile;
  return options;
}

inline uint64_t PixelsPerFrame(const PlannerOptions& options) {
  return static_cast<uint64_t>(options.width) * static_cast<uint64_t>(options.height);
}

// The task's pixels traced in the animation, in the task's pixel order.
inline std::vector<float> Trace(const TraceTask& task, const Animation& animation, int width) {
  std::vector<float> rgb;
  rgb.reserve(task.pixels.size() * 3);
  task.pixels.ForEach([&](uint32_t index) {
    const Rgb value = animation(task.frame, static_cast<int>(index % width),
                                static_cast<int>(index / width));
    rgb.insert(rgb.end(), value.begin(), value.end());
  });
  return rgb;
}

inline Rgb ValueAt(const FinishedFrame& frame, int width, int x, int y) {
  const size_t offset = (static_cast<size_t>(y) * width + x) * 3;
  return {frame.rgb[offset], frame.rgb[offset + 1], frame.rgb[offset + 2]};
}

// Pixels (over all frames, keyed by frame number) whose value differs from the animation's.
inline uint64_t CountWrongPixels(const std::map<int, FinishedFrame>& frames, const PlannerOptions& options,
                                 const Animation& animation) {
  uint64_t wrong = 0;
  for (const auto& [f, frame] : frames) {
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) wrong += ValueAt(frame, options.width, x, y) != animation(f, x, y);
    }
  }
  return wrong;
}

}  // namespace tcfarm::planner_test
