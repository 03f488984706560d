// What a job's coherence relies on (farm/job_coherence.h): in every strategy, a pixel a
// frame does not trace holds the previous frame's bits. Search and guarded copy a bin's
// left end into the frames inside it, with a tolerance too; exact copies a pixel's latest
// trace until its horizon.
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "coordinator/planner/planner.h"
#include "coordinator/planner/planner_test_support.h"

namespace tcfarm {
namespace {

using planner_test::Options;
using planner_test::Rgb;

// Pixels that hold a value for a random while and then take another from a few levels,
// so that bins' ends are often equal (within a tolerance too) while frames inside differ.
planner_test::Animation Flickers(uint32_t seed, int frames, int pixels) {
  std::mt19937 random(seed);
  auto values = std::make_shared<std::vector<Rgb>>(static_cast<size_t>(frames) * pixels);
  for (int p = 0; p < pixels; ++p) {
    Rgb value{0.5f, 0.25f, 0.0f};
    for (int f = 0; f < frames; ++f) {
      if (random() % 4 == 0) value[random() % 3] = 0.1f * static_cast<float>(random() % 4);
      (*values)[static_cast<size_t>(f) * pixels + p] = value;
    }
  }
  return [values, pixels](int frame, int x, int y) {
    return (*values)[static_cast<size_t>(frame) * pixels + static_cast<size_t>(y) * 8 + x];
  };
}

// The first frame after `frame` (up to frame + window + 1) whose value differs from the
// one before it: the true horizon.
int32_t Horizon(const planner_test::Animation& animation, int frame, int window, int x, int y) {
  int32_t h = frame + 1;
  while (h <= frame + window && animation(h, x, y) == animation(h - 1, x, y)) ++h;
  return h;
}

std::map<int, FinishedFrame> Render(Strategy strategy, const PlannerOptions& options,
                                    const planner_test::Animation& animation) {
  std::unique_ptr<Planner> planner = MakePlanner(strategy, options);
  std::map<int, FinishedFrame> frames;
  for (int round = 0; !planner->Done() && round < 100000; ++round) {
    for (const TraceTask& task : planner->TakeReadyTasks()) {
      const std::vector<float> rgb = planner_test::Trace(task, animation, options.width);
      std::vector<int32_t> horizons;
      if (task.window > 0) {
        task.pixels.ForEach([&](uint32_t pixel) {
          horizons.push_back(Horizon(animation, task.frame, task.window, static_cast<int>(pixel % options.width),
                                     static_cast<int>(pixel / options.width)));
        });
      }
      planner->OnResult(task.id, rgb.data(), rgb.size(), horizons.data(), horizons.size());
    }
    for (FinishedFrame& frame : planner->TakeFinishedFrames()) frames[frame.frame] = std::move(frame);
  }
  EXPECT_TRUE(planner->Done());
  return frames;
}

TEST(UntracedPixels, HoldThePreviousFramesBitsInEveryStrategy) {
  struct Case {
    Strategy strategy;
    int binWidth;
    float tolerance;
  };
  for (const Case& c : {Case{Strategy::kBrute, 2, 0}, Case{Strategy::kSearch, 6, 0},
                        Case{Strategy::kSearch, 9, 0.15f}, Case{Strategy::kGuarded, 7, 0},
                        Case{Strategy::kGuarded, 5, 0.15f}, Case{Strategy::kExact, 8, 0},
                        Case{Strategy::kExact, 1, 0}}) {
    PlannerOptions options = Options(8, 6, 23, c.binWidth, /*coarseTile=*/4);
    options.tolerance = c.tolerance;
    options.maxTaskPixels = 7;
    const planner_test::Animation animation = Flickers(static_cast<uint32_t>(c.binWidth), 23, 48);
    const std::map<int, FinishedFrame> frames = Render(c.strategy, options, animation);
    ASSERT_EQ(frames.size(), 23u) << StrategyName(c.strategy);
    uint64_t untraced = 0;
    for (int f = 1; f < 23; ++f) {
      for (size_t p = 0; p < 48; ++p) {
        if (frames.at(f).traced[p]) continue;
        ++untraced;
        EXPECT_EQ(std::memcmp(&frames.at(f).rgb[3 * p], &frames.at(f - 1).rgb[3 * p], 3 * sizeof(float)), 0)
            << StrategyName(c.strategy) << " n " << c.binWidth << " tolerance " << c.tolerance << ": pixel " << p
            << " of frame " << f;
      }
    }
    // Every strategy but brute force (and exact with segments of one frame) copies.
    if (c.binWidth > 2) {
      EXPECT_GT(untraced, 100u) << StrategyName(c.strategy);
    }
  }
}

}  // namespace
}  // namespace tcfarm
