#include "coordinator/planner/exact_planner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "coordinator/planner/planner.h"
#include "coordinator/planner/planner_test_support.h"

namespace tcfarm {
namespace {

using planner_test::Options;  // binWidth is the segment length here
using planner_test::PixelsPerFrame;
using planner_test::Rgb;

int SegmentEnd(const PlannerOptions& options, int frame) {
  const long long end = (static_cast<long long>(frame) / options.binWidth + 1) * options.binWidth;
  return static_cast<int>(std::min<long long>(end, options.frameCount) - 1);
}

bool IsSegmentFirst(const PlannerOptions& options, int frame) { return frame % options.binWidth == 0; }

// The fake tracer's world: every pixel's value at every frame, and when it changes.
class Animation {
 public:
  Animation(int width, int height, int frames, const std::function<Rgb(int frame, int x, int y)>& value)
      : pixels_(width * height), frames_(frames) {
    values_.resize(static_cast<size_t>(frames) * pixels_);
    for (int f = 0; f < frames; ++f) {
      for (int p = 0; p < pixels_; ++p) values_[Index(f, p)] = value(f, p % width, p / width);
    }
    // nextChange_[f][p]: the first frame h > f whose value differs from frame h-1's; frames if none.
    nextChange_.assign(values_.size(), frames);
    for (int f = frames - 2; f >= 0; --f) {
      for (int p = 0; p < pixels_; ++p) {
        nextChange_[Index(f, p)] = Changes(f + 1, p) ? f + 1 : nextChange_[Index(f + 1, p)];
      }
    }
  }

  const Rgb& At(int frame, int pixel) const { return values_[Index(frame, pixel)]; }
  bool Changes(int frame, int pixel) const { return frame > 0 && At(frame, pixel) != At(frame - 1, pixel); }
  // The true horizon of a pixel traced at `frame` with a look-ahead of `window` frames.
  int32_t Horizon(int frame, int pixel, int window) const {
    return std::min(nextChange_[Index(frame, pixel)], frame + window + 1);
  }
  int Frames() const { return frames_; }

 private:
  size_t Index(int frame, int pixel) const { return static_cast<size_t>(frame) * pixels_ + pixel; }

  int pixels_;
  int frames_;
  std::vector<Rgb> values_;
  std::vector<int32_t> nextChange_;
};

// What the fake worker reports as a pixel's horizon, given the truth.
using HorizonPolicy = std::function<int32_t(int frame, uint32_t pixel, int window, int32_t truth)>;

int32_t TrueHorizon(int, uint32_t, int, int32_t truth) { return truth; }

struct TracedResult {
  std::vector<float> rgb;
  std::vector<int32_t> horizons;  // empty for window 0
};

TracedResult Trace(const TraceTask& task, const Animation& animation, const HorizonPolicy& policy) {
  TracedResult result;
  task.pixels.ForEach([&](uint32_t pixel) {
    const Rgb& value = animation.At(task.frame, static_cast<int>(pixel));
    result.rgb.insert(result.rgb.end(), value.begin(), value.end());
    if (task.window > 0) {
      const int32_t truth = animation.Horizon(task.frame, static_cast<int>(pixel), task.window);
      result.horizons.push_back(policy(task.frame, pixel, task.window, truth));
    }
  });
  return result;
}

struct RenderRun {
  std::map<int, FinishedFrame> frames;
  size_t maxLiveFrames = 0;
  size_t maxOutstandingFrames = 0;  // distinct frames with tasks in flight at once
  uint64_t traced = 0;
};

// Drives a planner to the end, answering one randomly chosen outstanding task at a
// time, and checks on the way what the exact planner promises about its tasks: the
// window reaches the segment's end, and a segment's frame is handed out only when every
// earlier frame of the segment has finished.
RenderRun Drive(Planner& planner, const PlannerOptions& options, const Animation& animation, uint32_t seed = 1,
                const HorizonPolicy& policy = TrueHorizon) {
  std::mt19937 rng(seed);
  std::vector<TraceTask> outstanding;
  std::set<uint64_t> ids;
  RenderRun run;
  for (;;) {
    for (TraceTask& task : planner.TakeReadyTasks()) {
      EXPECT_TRUE(ids.insert(task.id).second) << "task " << task.id << " emitted twice";
      EXPECT_LE(task.pixels.size(), options.maxTaskPixels);
      EXPECT_FALSE(task.pixels.empty());
      EXPECT_EQ(task.window, SegmentEnd(options, task.frame) - task.frame) << "frame " << task.frame;
      const int first = task.frame / options.binWidth * options.binWidth;
      for (int f = first; f < task.frame; ++f) {
        if (static_cast<size_t>(f) < options.keptFrames.size() && options.keptFrames[f]) continue;
        EXPECT_EQ(run.frames.count(f), 1u) << "frame " << task.frame << " handed out before frame " << f;
      }
      for (const TraceTask& other : outstanding) {
        if (other.frame / options.binWidth == task.frame / options.binWidth) {
          EXPECT_EQ(other.frame, task.frame);
        }
      }
      outstanding.push_back(std::move(task));
    }
    std::set<int> outstandingFrames;
    for (const TraceTask& task : outstanding) outstandingFrames.insert(task.frame);
    run.maxOutstandingFrames = std::max(run.maxOutstandingFrames, outstandingFrames.size());
    if (outstanding.empty()) break;
    std::swap(outstanding[std::uniform_int_distribution<size_t>(0, outstanding.size() - 1)(rng)], outstanding.back());
    const TraceTask task = std::move(outstanding.back());
    outstanding.pop_back();
    const TracedResult result = Trace(task, animation, policy);
    EXPECT_TRUE(planner.OnResult(task.id, result.rgb.data(), result.rgb.size(),
                                 result.horizons.empty() ? nullptr : result.horizons.data(), result.horizons.size()));
    run.maxLiveFrames = std::max(run.maxLiveFrames, planner.LiveFrames());
    for (FinishedFrame& frame : planner.TakeFinishedFrames()) {
      const int number = frame.frame;
      EXPECT_TRUE(run.frames.emplace(number, std::move(frame)).second) << "frame " << number << " finished twice";
    }
  }
  EXPECT_TRUE(planner.Done()) << "the planner stalled with no task outstanding";
  run.traced = planner.TracedPixels();
  if (options.keptFrames.empty()) {
    EXPECT_EQ(planner.TracedPixels() + planner.CopiedPixels(), PixelsPerFrame(options) * options.frameCount);
  }
  return run;
}

RenderRun Render(const PlannerOptions& options, const Animation& animation, uint32_t seed = 1,
                 const HorizonPolicy& policy = TrueHorizon) {
  ExactPlanner planner(options);
  RenderRun run = Drive(planner, options, animation, seed, policy);
  EXPECT_EQ(planner.InFlightTasks(), 0u);
  return run;
}

// Every frame finished once, bit-identical to brute force; returns the traced count.
uint64_t ExpectBruteForceValues(const RenderRun& run, const PlannerOptions& options, const Animation& animation) {
  EXPECT_EQ(run.frames.size(), static_cast<size_t>(options.frameCount));
  uint64_t traced = 0;
  for (const auto& [f, frame] : run.frames) {
    EXPECT_EQ(frame.rgb.size(), PixelsPerFrame(options) * 3);
    EXPECT_EQ(frame.traced.size(), PixelsPerFrame(options));
    EXPECT_EQ(frame.tracedCount, static_cast<uint64_t>(std::count(frame.traced.begin(), frame.traced.end(), 1)));
    for (uint64_t p = 0; p < PixelsPerFrame(options); ++p) {
      const Rgb value = {frame.rgb[p * 3], frame.rgb[p * 3 + 1], frame.rgb[p * 3 + 2]};
      if (value != animation.At(f, static_cast<int>(p))) {
        ADD_FAILURE() << "frame " << f << " pixel " << p << " differs from brute force";
        return traced;
      }
    }
    traced += frame.tracedCount;
  }
  EXPECT_EQ(traced, run.traced);
  return traced;
}

// With exact horizons a pixel is traced at a segment's first frame and where its value
// changes, and nowhere else.
void ExpectTracedExactlyWhereChanged(const RenderRun& run, const PlannerOptions& options,
                                     const Animation& animation) {
  for (const auto& [f, frame] : run.frames) {
    for (uint64_t p = 0; p < PixelsPerFrame(options); ++p) {
      const bool expected = IsSegmentFirst(options, f) || animation.Changes(f, static_cast<int>(p));
      if (frame.traced[p] != expected) {
        ADD_FAILURE() << "frame " << f << " pixel " << p << " traced " << int{frame.traced[p]} << ", expected "
                      << expected;
        return;
      }
    }
  }
}

Rgb StaticValue(int, int x, int y) { return {0.1f * x, 0.2f * y, 0.3f}; }

Rgb NoisyValue(int frame, int x, int y) {
  const unsigned hash = static_cast<unsigned>(frame * 73856093) ^ static_cast<unsigned>(x * 19349663) ^
                        static_cast<unsigned>(y * 83492791);
  return {static_cast<float>(hash % 1000) / 1000.0f, static_cast<float>(frame), 0.0f};
}

// Piecewise-constant pixels from a small palette that change at random frames, at a
// rate drawn per pixel (some never change, some change nearly every frame).
Animation RandomFlickers(uint32_t seed, int frames, int width, int height) {
  std::mt19937 rng(seed);
  const float palette[] = {0.0f, 0.25f, 0.5f, 1.0f};
  std::vector<Rgb> values(static_cast<size_t>(frames) * width * height);
  for (int p = 0; p < width * height; ++p) {
    Rgb current = {palette[rng() % 4], 0.5f, 0.0f};
    const double changeRate = std::uniform_real_distribution<double>(0.0, 0.7)(rng);
    for (int f = 0; f < frames; ++f) {
      if (std::bernoulli_distribution(changeRate)(rng)) current[rng() % 3] = palette[rng() % 4];
      values[static_cast<size_t>(f) * width * height + p] = current;
    }
  }
  return Animation(width, height, frames, [&](int f, int x, int y) {
    return values[(static_cast<size_t>(f) * height + y) * width + x];
  });
}

TEST(ExactPlanner, RandomizedIsBruteForceAndTracesOnlyChanges) {
  std::mt19937 rng(20240601);
  for (int round = 0; round < 150; ++round) {
    auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    PlannerOptions options = Options(pick(1, 11), pick(1, 8), pick(1, 45), pick(1, 16));
    options.maxTaskPixels = static_cast<uint32_t>(pick(1, 40));
    options.maxLiveBins = pick(1, 5);
    const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
    const RenderRun run = Render(options, animation, rng());
    ExpectBruteForceValues(run, options, animation);
    ExpectTracedExactlyWhereChanged(run, options, animation);
    EXPECT_LE(run.maxLiveFrames, static_cast<size_t>(options.maxLiveBins));
    if (HasFailure()) {
      ADD_FAILURE() << "round " << round << ": " << options.width << "x" << options.height << " N "
                    << options.frameCount << " L " << options.binWidth << " chunk " << options.maxTaskPixels
                    << " segments " << options.maxLiveBins;
      return;
    }
  }
}

// Finished frames are copied into buffers the pool hands out (written frames' buffers,
// here larger and full of NaN), and come out brute force's all the same.
TEST(ExactPlanner, FinishedFramesFillRecycledBuffers) {
  std::mt19937 rng(11);
  PlannerOptions options = Options(7, 5, 19, 6);
  options.maxLiveBins = 2;
  const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
  options.frameBuffers = std::make_shared<FrameBufferPool>(32);
  for (int i = 0; i < 12; ++i) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    options.frameBuffers->Give(std::vector<float>(PixelsPerFrame(options) * 3 + 5, nan));
  }
  const RenderRun run = Render(options, animation);
  ExpectBruteForceValues(run, options, animation);
  EXPECT_EQ(options.frameBuffers->Held(), 0u);  // 19 frames took the 12 buffers
}

// A resumed job: each segment starts again at its first frame not kept, with a full
// trace there; kept frames before it are never traced again, and every frame produced is
// brute force's, as in an uninterrupted run.
TEST(ExactPlanner, ResumedSegmentsStartAtTheirFirstFrameNotKept) {
  std::mt19937 rng(7);
  PlannerOptions options = Options(6, 5, 23, 8);  // segments [0,7] [8,15] [16,22]
  const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
  options.keptFrames.assign(23, false);
  for (int f : {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 12, 13}) options.keptFrames[f] = true;  // 11 was not written
  const RenderRun run = Render(options, animation);
  std::set<int> produced;
  for (const auto& [f, frame] : run.frames) {
    produced.insert(f);
    for (int p = 0; p < 30; ++p) {
      const Rgb value{frame.rgb[p * 3], frame.rgb[p * 3 + 1], frame.rgb[p * 3 + 2]};
      EXPECT_EQ(value, animation.At(f, p)) << "pixel " << p << " of frame " << f;
    }
  }
  std::set<int> expected;
  for (int f = 11; f < 23; ++f) expected.insert(f);
  EXPECT_EQ(produced, expected);  // segment 0 is skipped whole, segment 1 starts at 11
  EXPECT_EQ(run.frames.at(11).tracedCount, 30u);
  EXPECT_EQ(run.frames.at(16).tracedCount, 30u);
}

TEST(ExactPlanner, StaticSceneInOneSegmentTracesOneFrame) {
  for (int length : {12, 13, 1000, std::numeric_limits<int>::max()}) {
    const PlannerOptions options = Options(7, 5, 12, length);
    const Animation animation(7, 5, 12, StaticValue);
    const RenderRun run = Render(options, animation);
    EXPECT_EQ(ExpectBruteForceValues(run, options, animation), 35u) << length;
    EXPECT_EQ(run.frames.at(0).tracedCount, 35u);
  }
}

// A frame's pixels are spread over the workers, no task below kMinTaskPixels; each task
// names its segment (chain) and its frame's place in it (step), for the job's span.
TEST(ExactPlanner, AFramesPixelsAreSpreadOverTheWorkersAndTasksNameTheirChain) {
  PlannerOptions options = Options(256, 64, 10, 5);  // 16384 pixels; segments [0,4] [5,9]
  options.workers = 4;
  ExactPlanner planner(options);
  std::vector<TraceTask> first = planner.TakeReadyTasks();
  std::map<int, int> tasksPerSegment;
  for (const TraceTask& task : first) {
    EXPECT_EQ(task.pixels.size(), 4096u);
    EXPECT_EQ(task.chain, task.frame / 5);
    EXPECT_EQ(task.step, 0);
    ++tasksPerSegment[task.chain];
  }
  EXPECT_EQ(tasksPerSegment, (std::map<int, int>{{0, 4}, {1, 4}}));
  planner.SetWorkers(64);  // more workers than kMinTaskPixels tasks: the floor holds
  const Animation animation(256, 64, 10, [](int frame, int x, int y) {
    Rgb value = StaticValue(frame, x, y);
    if (y < 20 && frame >= 2) value[0] = 0.5f;  // 20 rows change at frame 2
    return value;
  });
  for (const TraceTask& task : first) {
    const TracedResult result = Trace(task, animation, TrueHorizon);
    planner.OnResult(task.id, result.rgb.data(), result.rgb.size(), result.horizons.data(), result.horizons.size());
  }
  const std::vector<TraceTask> second = planner.TakeReadyTasks();
  ASSERT_EQ(second.size(), 2u);  // frame 2's 5120 pixels: 4096 and 1024
  EXPECT_EQ(second[0].pixels.size(), PlannerOptions::kMinTaskPixels);
  for (const TraceTask& task : second) {
    EXPECT_EQ(task.frame, 2);
    EXPECT_EQ(task.chain, 0);
    EXPECT_EQ(task.step, 2);
  }
}

TEST(ExactPlanner, StaticSceneTracesEachSegmentsFirstFrame) {
  // N = 10, L = 4: segments [0,3] [4,7] [8,9].
  const PlannerOptions options = Options(6, 4, 10, 4);
  const Animation animation(6, 4, 10, StaticValue);
  const RenderRun run = Render(options, animation);
  EXPECT_EQ(ExpectBruteForceValues(run, options, animation), 3u * 24u);
  for (int f : {0, 4, 8}) EXPECT_EQ(run.frames.at(f).tracedCount, 24u) << f;
}

TEST(ExactPlanner, OneChangingPixelIsTracedOnceMoreAndFramesBetweenAreCopied) {
  // Pixel (2, 1) takes a new value at frame 5 of the one segment [0, 9]: frame 0 in full,
  // then that pixel at 5; frames 1-4 and 6-9 are copies.
  const PlannerOptions options = Options(5, 3, 10, 10);
  const Animation animation(5, 3, 10, [](int frame, int x, int y) {
    Rgb value = StaticValue(frame, x, y);
    if (x == 2 && y == 1 && frame >= 5) value[2] = 0.9f;
    return value;
  });
  const RenderRun run = Render(options, animation);
  EXPECT_EQ(ExpectBruteForceValues(run, options, animation), 15u + 1u);
  EXPECT_EQ(run.frames.at(5).tracedCount, 1u);
  EXPECT_EQ(run.frames.at(5).traced[1 * 5 + 2], 1);
  for (int f : {1, 2, 3, 4, 6, 7, 8, 9}) EXPECT_EQ(run.frames.at(f).tracedCount, 0u) << f;
}

TEST(ExactPlanner, SegmentLengthOneIsBruteForce) {
  const PlannerOptions options = Options(7, 5, 9, 1);
  const Animation animation(7, 5, 9, StaticValue);  // even a still scene is traced in full
  ExactPlanner planner(options);
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_FALSE(tasks.empty());
  for (const TraceTask& task : tasks) EXPECT_EQ(task.window, 0);  // Drive checks every later task too
  const RenderRun run = Render(options, animation);
  EXPECT_EQ(ExpectBruteForceValues(run, options, animation), 9u * 35u);

  const Animation noisy(7, 5, 9, NoisyValue);
  EXPECT_EQ(ExpectBruteForceValues(Render(options, noisy, 3), options, noisy), 9u * 35u);
}

TEST(ExactPlanner, ConservativeHorizonsStayExactAndOnlyTraceMore) {
  std::mt19937 rng(99);
  for (int round = 0; round < 40; ++round) {
    auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    PlannerOptions options = Options(pick(1, 10), pick(1, 8), pick(2, 40), pick(2, 15));
    options.maxTaskPixels = static_cast<uint32_t>(pick(1, 30));
    options.maxLiveBins = pick(1, 4);
    const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
    std::mt19937 horizonRng(rng());
    // Every third pixel claims it may change at once; the others a random frame no later than the truth.
    const HorizonPolicy early = [&](int frame, uint32_t pixel, int, int32_t truth) {
      if (pixel % 3 == 0) return frame + 1;
      return std::uniform_int_distribution<int32_t>(frame + 1, truth)(horizonRng);
    };
    const RenderRun exact = Render(options, animation, 1);
    const RenderRun conservative = Render(options, animation, 2, early);
    const uint64_t exactTraced = ExpectBruteForceValues(exact, options, animation);
    const uint64_t conservativeTraced = ExpectBruteForceValues(conservative, options, animation);
    EXPECT_GE(conservativeTraced, exactTraced);
    for (const auto& [f, frame] : exact.frames) {
      for (size_t p = 0; p < frame.traced.size(); ++p) {
        if (frame.traced[p]) {
          EXPECT_EQ(conservative.frames.at(f).traced[p], 1) << "frame " << f << " pixel " << p;
        }
      }
    }
    if (HasFailure()) {
      ADD_FAILURE() << "round " << round;
      return;
    }
  }
  // Horizons of a + 1 everywhere: brute force's values at brute force's cost.
  const PlannerOptions options = Options(6, 5, 20, 7);
  const Animation animation(6, 5, 20, StaticValue);
  const RenderRun run = Render(options, animation, 4, [](int frame, uint32_t, int, int32_t) { return frame + 1; });
  EXPECT_EQ(ExpectBruteForceValues(run, options, animation), 20u * 30u);
}

TEST(ExactPlanner, BadHorizonsThrowAndChangeNothing) {
  const PlannerOptions options = Options(3, 2, 4, 4);  // one segment: frame 0 has window 3
  const Animation animation(3, 2, 4, StaticValue);
  ExactPlanner planner(options);
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_EQ(tasks.size(), 1u);
  const TraceTask task = tasks[0];
  EXPECT_EQ(task.window, 3);
  const TracedResult good = Trace(task, animation, TrueHorizon);
  ASSERT_EQ(good.horizons, std::vector<int32_t>(6, 4));  // valid through the window

  auto rejects = [&](const int32_t* horizons, size_t count) {
    EXPECT_THROW(planner.OnResult(task.id, good.rgb.data(), good.rgb.size(), horizons, count), std::invalid_argument);
  };
  rejects(nullptr, 0);
  rejects(nullptr, 6);
  rejects(good.horizons.data(), 5);
  std::vector<int32_t> bad = good.horizons;
  bad.push_back(4);
  rejects(bad.data(), bad.size());
  for (int32_t horizon : {0, -1, 5, std::numeric_limits<int32_t>::max(), std::numeric_limits<int32_t>::min()}) {
    bad = good.horizons;
    bad[2] = horizon;
    rejects(bad.data(), bad.size());
  }
  EXPECT_EQ(planner.TracedPixels(), 0u);
  EXPECT_TRUE(planner.TakeReadyTasks().empty());
  EXPECT_TRUE(planner.TakeFinishedFrames().empty());

  bad = good.horizons;
  bad[2] = 5;
  try {
    planner.OnResult(task.id, good.rgb.data(), good.rgb.size(), bad.data(), bad.size());
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "result of task 1 (frame 0) has horizon 5 at pixel 2; expected 1 .. 4");
  }
  try {
    planner.OnResult(task.id, good.rgb.data(), good.rgb.size());
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()),
              "result of task 1 (frame 0) has 0 horizons; expected 6 (one per pixel, window 3)");
  }

  EXPECT_TRUE(planner.OnResult(task.id, good.rgb.data(), good.rgb.size(), good.horizons.data(), good.horizons.size()));
  EXPECT_FALSE(planner.OnResult(task.id, nullptr, 0));  // re-delivered: ignored
  EXPECT_EQ(planner.TakeFinishedFrames().size(), 4u);
  EXPECT_TRUE(planner.Done());
  EXPECT_EQ(planner.TracedPixels(), 6u);
  EXPECT_EQ(planner.CopiedPixels(), 18u);
}

TEST(ExactPlanner, HorizonOfTheFrameItselfIsRejected) {
  // Second frame of a segment: a pixel traced at 2 may not claim horizon 2.
  const PlannerOptions options = Options(2, 1, 6, 6);
  const Animation animation(2, 1, 6, [](int frame, int x, int) {
    return Rgb{x == 0 && frame >= 2 ? 1.0f : 0.0f, 0.0f, 0.0f};
  });
  ExactPlanner planner(options);
  const TraceTask first = planner.TakeReadyTasks().at(0);
  const TracedResult result = Trace(first, animation, TrueHorizon);
  EXPECT_EQ(result.horizons, (std::vector<int32_t>{2, 6}));
  ASSERT_TRUE(planner.OnResult(first.id, result.rgb.data(), result.rgb.size(), result.horizons.data(), 2));
  const std::vector<TraceTask> next = planner.TakeReadyTasks();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].frame, 2);
  EXPECT_EQ(next[0].window, 3);
  EXPECT_EQ(next[0].pixels, PixelSet::FromSortedIndices({0}));
  const std::vector<float> rgb = {1.0f, 0.0f, 0.0f};
  for (int32_t horizon : {2, 1, 7}) {
    EXPECT_THROW(planner.OnResult(next[0].id, rgb.data(), 3, &horizon, 1), std::invalid_argument) << horizon;
  }
  const int32_t valid = 6;
  EXPECT_TRUE(planner.OnResult(next[0].id, rgb.data(), 3, &valid, 1));
  EXPECT_EQ(planner.TakeFinishedFrames().size(), 6u);
  EXPECT_TRUE(planner.Done());
}

TEST(ExactPlanner, HorizonsOfTheLastFrameAreNotNeeded) {
  // A segment's last frame has window 0: no horizons wanted, any sent are ignored.
  const PlannerOptions options = Options(2, 2, 3, 3);
  const Animation animation(2, 2, 3, NoisyValue);  // every pixel changes every frame
  ExactPlanner planner(options);
  for (int frame = 0; frame < 3; ++frame) {
    const std::vector<TraceTask> tasks = planner.TakeReadyTasks();
    ASSERT_EQ(tasks.size(), 1u);
    EXPECT_EQ(tasks[0].frame, frame);
    EXPECT_EQ(tasks[0].window, 2 - frame);
    const TracedResult result = Trace(tasks[0], animation, TrueHorizon);
    if (frame < 2) {
      EXPECT_EQ(result.horizons, std::vector<int32_t>(4, frame + 1));
      EXPECT_TRUE(planner.OnResult(tasks[0].id, result.rgb.data(), result.rgb.size(), result.horizons.data(), 4));
    } else {
      const std::vector<int32_t> ignored = {0, 0};
      EXPECT_TRUE(planner.OnResult(tasks[0].id, result.rgb.data(), result.rgb.size(), ignored.data(), 2));
    }
  }
  EXPECT_EQ(planner.TakeFinishedFrames().size(), 3u);
  EXPECT_TRUE(planner.Done());
  EXPECT_EQ(planner.TracedPixels(), 12u);
}

TEST(ExactPlanner, SegmentsStartInOrderAndRunInParallel) {
  // N = 10, L = 4: segments [0,3] [4,7] [8,9], all three live at once.
  PlannerOptions options = Options(4, 4, 10, 4);
  options.maxTaskPixels = 5;
  ExactPlanner planner(options);
  std::map<int, std::set<int>> windowsByFrame;
  for (const TraceTask& task : planner.TakeReadyTasks()) windowsByFrame[task.frame].insert(task.window);
  EXPECT_EQ(windowsByFrame, (std::map<int, std::set<int>>{{0, {3}}, {4, {3}}, {8, {1}}}));
  EXPECT_EQ(planner.InFlightTasks(), 3u * 4u);  // 16 pixels in chunks of 5

  options.maxLiveBins = 2;
  ExactPlanner twoLive(options);
  windowsByFrame.clear();
  for (const TraceTask& task : twoLive.TakeReadyTasks()) windowsByFrame[task.frame].insert(task.window);
  EXPECT_EQ(windowsByFrame, (std::map<int, std::set<int>>{{0, {3}}, {4, {3}}}));
}

TEST(ExactPlanner, ShuffledResultsAcrossManySegments) {
  PlannerOptions options = Options(16, 12, 64, 8);
  options.maxTaskPixels = 16;
  options.maxLiveBins = 8;
  const Animation animation = RandomFlickers(5, 64, 16, 12);
  const RenderRun run = Render(options, animation, 12345);
  ExpectBruteForceValues(run, options, animation);
  ExpectTracedExactlyWhereChanged(run, options, animation);
  EXPECT_EQ(run.maxOutstandingFrames, 8u);  // one frame per live segment, all eight busy at the start
}

TEST(ExactPlanner, LiveFramesBoundedOnALongJob) {
  PlannerOptions options = Options(9, 7, 300, 10);
  options.maxLiveBins = 3;
  const Animation animation = RandomFlickers(17, 300, 9, 7);
  const RenderRun run = Render(options, animation, 8);
  ExpectBruteForceValues(run, options, animation);
  // One working frame per live segment; finished frames are handed out as they finish.
  EXPECT_LE(run.maxLiveFrames, 3u);
  EXPECT_LE(run.maxOutstandingFrames, 3u);
}

TEST(ExactPlanner, RejectsBadResults) {
  const PlannerOptions options = Options(3, 2, 2, 1);
  ExactPlanner planner(options);
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_EQ(tasks.size(), 2u);
  const Animation animation(3, 2, 2, StaticValue);
  const TracedResult result = Trace(tasks[0], animation, TrueHorizon);
  EXPECT_THROW(planner.OnResult(0, result.rgb.data(), result.rgb.size()), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(999, result.rgb.data(), result.rgb.size()), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(tasks[0].id, result.rgb.data(), result.rgb.size() - 1), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(tasks[0].id, nullptr, result.rgb.size()), std::invalid_argument);
  std::vector<float> poisoned = result.rgb;
  poisoned[1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(planner.OnResult(tasks[0].id, poisoned.data(), poisoned.size()), std::invalid_argument);
  EXPECT_EQ(planner.TracedPixels(), 0u);
  EXPECT_TRUE(planner.OnResult(tasks[0].id, result.rgb.data(), result.rgb.size()));
  EXPECT_FALSE(planner.OnResult(tasks[0].id, result.rgb.data(), result.rgb.size()));
}

TEST(ExactPlanner, BadOptionsThrow) {
  PlannerOptions options = Options(4, 4, 10, 0);
  try {
    ExactPlanner planner(options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()),
              "PlannerOptions.binWidth is 0; expected >= 1 (the segment length; 1 traces every pixel)");
  }
  options.binWidth = 3;
  options.frameCount = 0;
  EXPECT_THROW(ExactPlanner{options}, std::invalid_argument);
  options.frameCount = 10;
  options.maxLiveBins = 0;
  EXPECT_THROW(ExactPlanner{options}, std::invalid_argument);
  options.maxLiveBins = 1;
  options.maxTaskPixels = 0;
  EXPECT_THROW(ExactPlanner{options}, std::invalid_argument);
}

TEST(ExactPlanner, MadeThroughTheInterface) {
  PlannerOptions options = Options(8, 6, 25, 6);
  const Animation animation = RandomFlickers(3, 25, 8, 6);
  std::unique_ptr<Planner> planner = MakePlanner(Strategy::kExact, options);
  const RenderRun run = Drive(*planner, options, animation, 21);
  ExpectBruteForceValues(run, options, animation);
  ExpectTracedExactlyWhereChanged(run, options, animation);
}

}  // namespace
}  // namespace tcfarm
