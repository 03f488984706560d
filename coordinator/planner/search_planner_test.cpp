#include "coordinator/planner/search_planner.h"
#include "coordinator/planner/planner_test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace tcfarm {
namespace {

using planner_test::Animation;
using planner_test::CountWrongPixels;
using planner_test::Options;
using planner_test::PixelsPerFrame;
using planner_test::Rgb;
using planner_test::Trace;
using planner_test::ValueAt;

struct RenderRun {
  std::map<int, FinishedFrame> frames;
  size_t maxLiveFrames = 0;
  size_t maxInFlightTasks = 0;
  uint64_t tasks = 0;
};

// Drives a planner to the end, answering one randomly chosen outstanding task at a
// time, so results come back in an order unrelated to the order of emission.
RenderRun Drive(SearchPlanner& planner, const PlannerOptions& options, const Animation& animation, uint32_t seed = 1) {
  std::mt19937 rng(seed);
  std::vector<TraceTask> outstanding;
  std::set<uint64_t> ids;
  RenderRun run;
  for (;;) {
    for (TraceTask& task : planner.TakeReadyTasks()) {
      EXPECT_TRUE(ids.insert(task.id).second) << "task " << task.id << " emitted twice";
      EXPECT_LE(task.pixels.size(), options.maxTaskPixels);
      EXPECT_FALSE(task.pixels.empty());
      outstanding.push_back(std::move(task));
    }
    run.maxInFlightTasks = std::max(run.maxInFlightTasks, outstanding.size());
    if (outstanding.empty()) break;
    std::swap(outstanding[std::uniform_int_distribution<size_t>(0, outstanding.size() - 1)(rng)], outstanding.back());
    const TraceTask task = std::move(outstanding.back());
    outstanding.pop_back();
    const std::vector<float> rgb = Trace(task, animation, options.width);
    EXPECT_TRUE(planner.OnResult(task.id, rgb.data(), rgb.size()));
    ++run.tasks;
    run.maxLiveFrames = std::max(run.maxLiveFrames, planner.LiveFrames());
    for (FinishedFrame& frame : planner.TakeFinishedFrames()) {
      const int number = frame.frame;
      EXPECT_TRUE(run.frames.emplace(number, std::move(frame)).second) << "frame " << number << " finished twice";
    }
  }
  EXPECT_TRUE(planner.Done()) << "the planner stalled with no task outstanding";
  EXPECT_EQ(planner.InFlightTasks(), 0u);
  return run;
}

RenderRun Render(const PlannerOptions& options, const Animation& animation, uint32_t seed = 1) {
  SearchPlanner planner(options);
  RenderRun run = Drive(planner, options, animation, seed);
  EXPECT_EQ(planner.TracedPixels() + planner.CopiedPixels(), PixelsPerFrame(options) * options.frameCount);
  return run;
}

// Every frame finished exactly once, with consistent shapes and counts.
uint64_t CheckFramesAndCountTraced(const RenderRun& run, const PlannerOptions& options) {
  EXPECT_EQ(run.frames.size(), static_cast<size_t>(options.frameCount));
  uint64_t traced = 0;
  for (int f = 0; f < options.frameCount; ++f) {
    auto found = run.frames.find(f);
    if (found == run.frames.end()) {
      ADD_FAILURE() << "frame " << f << " never finished";
      continue;
    }
    const FinishedFrame& frame = found->second;
    EXPECT_EQ(frame.rgb.size(), PixelsPerFrame(options) * 3);
    EXPECT_EQ(frame.traced.size(), PixelsPerFrame(options));
    const uint64_t flagged = static_cast<uint64_t>(std::count(frame.traced.begin(), frame.traced.end(), 1));
    EXPECT_EQ(frame.tracedCount, flagged) << "frame " << f;
    traced += frame.tracedCount;
  }
  return traced;
}

// The paper's algorithm written the obvious way: sequential, one pixel at a time
// (Search treats every pixel independently). The planner must agree with it bit for bit.
struct Reference {
  std::vector<std::vector<Rgb>> values;  // [frame][pixel]
  std::vector<std::vector<uint8_t>> traced;
  uint64_t tracedCount = 0;
};

Reference RenderReference(const PlannerOptions& options, const Animation& animation) {
  const int width = options.width, pixels = options.width * options.height, n = options.binWidth;
  const int frames = options.frameCount;
  Reference ref;
  ref.values.assign(frames, std::vector<Rgb>(pixels));
  ref.traced.assign(frames, std::vector<uint8_t>(pixels, 0));
  auto trace = [&](int f, int p) {
    ref.values[f][p] = animation(f, p % width, p / width);
    ref.traced[f][p] = 1;
    ++ref.tracedCount;
  };
  auto equal = [&](const Rgb& a, const Rgb& b) {
    if (options.tolerance == 0) return a == b;
    for (int c = 0; c < 3; ++c) {
      if (std::fabs(a[c] - b[c]) > options.tolerance) return false;
    }
    return true;
  };
  std::function<void(int, int, int)> search = [&](int p, int l, int r) {
    if (r - l <= 1) return;
    if (equal(ref.values[l][p], ref.values[r][p])) {
      for (int f = l + 1; f < r; ++f) ref.values[f][p] = ref.values[l][p];
      return;
    }
    const int j = (l + r) / 2;
    trace(j, p);
    search(p, l, j);
    search(p, j, r);
  };
  std::vector<int> ends = {0};
  for (int end = 0; end < frames - 1;) ends.push_back(end = std::min(end + n - 1, frames - 1));
  for (int end : ends) {
    for (int p = 0; p < pixels; ++p) trace(end, p);
  }
  for (size_t b = 0; b + 1 < ends.size(); ++b) {
    for (int p = 0; p < pixels; ++p) search(p, ends[b], ends[b + 1]);
  }
  return ref;
}

void ExpectMatchesReference(const RenderRun& run, const PlannerOptions& options, const Reference& ref) {
  for (const auto& [f, frame] : run.frames) {
    for (int p = 0; p < options.width * options.height; ++p) {
      ASSERT_EQ(ValueAt(frame, options.width, p % options.width, p / options.width), ref.values[f][p])
          << "frame " << f << " pixel " << p;
      ASSERT_EQ(frame.traced[p], ref.traced[f][p]) << "frame " << f << " pixel " << p;
    }
  }
}

// Every channel of every pixel only ever grows, so a pixel equal at two frames is
// equal at every frame between: the paper's assumption holds, and the search must
// reproduce the animation exactly. A sweeping edge, a static texture, and a counter
// that steps at a pixel-dependent rate.
Rgb MonotoneAnimation(int frame, int x, int y) {
  const float edge = x < frame * 0.7f ? 1.0f : 0.25f;
  const float texture = 0.1f * static_cast<float>(y) + 0.01f * static_cast<float>(x);
  const float counter = (x + y) % 3 == 0 ? static_cast<float>((frame + x) / (2 + y % 4)) : 0.5f;
  return {edge, texture, counter};
}

Rgb StaticAnimation(int, int x, int y) { return {0.1f * x, 0.2f * y, 0.3f}; }

// Noise that changes every frame: the search can save nothing.
Rgb NoisyAnimation(int frame, int x, int y) {
  const unsigned hash = static_cast<unsigned>(frame * 73856093) ^ static_cast<unsigned>(x * 19349663) ^
                        static_cast<unsigned>(y * 83492791);
  return {static_cast<float>(hash % 1000) / 1000.0f, static_cast<float>(frame), 0.0f};
}

// A resumed job: bins whose frames are all kept are not planned; the others run as in an
// uninterrupted run and give the same frames, bit for bit, and the same traced masks.
TEST(SearchPlanner, ResumedJobPlansOnlyBinsNotKeptAndMatchesAnUninterruptedRun) {
  PlannerOptions options = Options(9, 7, 21, 5);  // bins [0,4] [4,8] [8,12] [12,16] [16,20]
  const Animation animation = [](int f, int x, int y) {
    return Rgb{static_cast<float>((x * 7 + y * 3 + f / 3) % 5), static_cast<float>(x == f % 9), 0.0f};
  };
  const RenderRun full = Render(options, animation);
  options.keptFrames.assign(21, false);
  for (int f : {0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 16}) options.keptFrames[f] = true;
  SearchPlanner planner(options);
  const RenderRun resumed = Drive(planner, options, animation);
  std::set<int> produced;
  uint64_t traced = 0, bound = 0;
  for (const auto& [f, frame] : resumed.frames) {
    produced.insert(f);
    EXPECT_EQ(frame.rgb, full.frames.at(f).rgb) << "frame " << f;
    EXPECT_EQ(frame.traced, full.frames.at(f).traced) << "frame " << f;
    traced += frame.tracedCount;
  }
  std::set<int> expected;
  for (int f = 8; f <= 20; ++f) expected.insert(f);
  EXPECT_EQ(produced, expected);  // bins [0,4] and [4,8] are kept whole
  EXPECT_EQ(planner.TracedPixels(), traced);
  for (int f = 8; f <= 20; ++f) bound += full.frames.at(f).tracedCount;
  EXPECT_EQ(traced, bound);
}

TEST(SearchPlanner, BinWidthTwoIsBruteForce) {
  const PlannerOptions options = Options(7, 5, 9, 2);
  const RenderRun run = Render(options, NoisyAnimation, 7);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 9u * 7u * 5u);
  for (const auto& [f, frame] : run.frames) {
    EXPECT_TRUE(std::all_of(frame.traced.begin(), frame.traced.end(), [](uint8_t t) { return t == 1; }));
  }
  EXPECT_EQ(CountWrongPixels(run.frames, options, NoisyAnimation), 0u);
}

TEST(SearchPlanner, BinWidthTwoIsBruteForceEvenForAStaticScene) {
  const PlannerOptions options = Options(4, 3, 6, 2);
  const RenderRun run = Render(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 6u * 4u * 3u);
}

TEST(SearchPlanner, StaticSceneTracesOnlyBinEnds) {
  // N = 10, n = 4: bins [0,3] [3,6] [6,9]; end frames 0, 3, 6, 9.
  PlannerOptions options = Options(6, 4, 10, 4);
  RenderRun run = Render(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 4u * 24u);
  for (int f : {0, 3, 6, 9}) EXPECT_EQ(run.frames.at(f).tracedCount, 24u) << f;
  EXPECT_EQ(CountWrongPixels(run.frames, options, StaticAnimation), 0u);

  // N = 11: a remainder bin [9, 10] adds frame 10 (equation 3 with d = 0: a + b = 4 + 1).
  options.frameCount = 11;
  run = Render(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 5u * 24u);
}

// Pixel (2, 1) takes a new value at changeFrame and keeps it.
Animation OnePixelChangingAt(int changeFrame) {
  return [changeFrame](int frame, int x, int y) {
    Rgb value = StaticAnimation(frame, x, y);
    if (x == 2 && y == 1 && frame >= changeFrame) value[2] = 0.9f;
    return value;
  };
}

TEST(SearchPlanner, OnePixelChangingOnceIsFoundByBinarySearch) {
  // One bin [0, 8], change at frame 3. The pixel differs at 0 and 8: trace at 4 (new
  // value). [0,4] differs: trace at 2 (old). [0,2] equal: copy into 1. [2,4] differs:
  // trace at 3. [2,3] and [3,4] are done. [4,8] equal: copy. Three traces.
  const PlannerOptions options = Options(5, 3, 9, 9);
  const Animation animation = OnePixelChangingAt(3);
  const RenderRun run = Render(options, animation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 2u * 15u + 3u);
  for (int f : {2, 3, 4}) EXPECT_EQ(run.frames.at(f).tracedCount, 1u) << f;
  EXPECT_EQ(CountWrongPixels(run.frames, options, animation), 0u);
}

TEST(SearchPlanner, OnePixelChangingInTheSecondBin) {
  // Bins [0,4] [4,8], change at frame 6. Bin [0,4]: equal ends, nothing traced inside.
  // Bin [4,8]: trace at 6 (new); [4,6] differs: trace at 5 (old); [6,8] equal: copy.
  const PlannerOptions options = Options(5, 3, 9, 5);
  const Animation animation = OnePixelChangingAt(6);
  const RenderRun run = Render(options, animation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 3u * 15u + 2u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, animation), 0u);
}

TEST(SearchPlanner, SingleFrameIsTracedFully) {
  const PlannerOptions options = Options(5, 4, 1, 8);
  const RenderRun run = Render(options, NoisyAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 20u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, NoisyAnimation), 0u);
}

TEST(SearchPlanner, TwoFramesAreBothTraced) {
  const PlannerOptions options = Options(5, 4, 2, 8);
  const RenderRun run = Render(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 40u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, StaticAnimation), 0u);
}

TEST(SearchPlanner, BinWidthAtLeastFrameCountMakesOneBin) {
  for (int binWidth : {6, 7, 50, std::numeric_limits<int>::max()}) {
    const PlannerOptions options = Options(6, 4, 6, binWidth);
    RenderRun run = Render(options, StaticAnimation);
    EXPECT_EQ(CheckFramesAndCountTraced(run, options), 2u * 24u) << binWidth;
    EXPECT_EQ(run.frames.at(0).tracedCount, 24u);
    EXPECT_EQ(run.frames.at(5).tracedCount, 24u);
    run = Render(options, MonotoneAnimation);
    CheckFramesAndCountTraced(run, options);
    EXPECT_EQ(CountWrongPixels(run.frames, options, MonotoneAnimation), 0u) << binWidth;
  }
}

TEST(SearchPlanner, RemainderBinEndsAtTheLastFrame) {
  // N - 1 = 11 = 3 * (n - 1) + 2: bins [0,3] [3,6] [6,9] [9,11].
  const PlannerOptions options = Options(6, 4, 12, 4);
  RenderRun run = Render(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 5u * 24u);
  for (int f : {0, 3, 6, 9, 11}) EXPECT_EQ(run.frames.at(f).tracedCount, 24u) << f;
  EXPECT_EQ(run.frames.at(10).tracedCount, 0u);

  run = Render(options, MonotoneAnimation, 3);
  CheckFramesAndCountTraced(run, options);
  EXPECT_EQ(CountWrongPixels(run.frames, options, MonotoneAnimation), 0u);
  ExpectMatchesReference(run, options, RenderReference(options, MonotoneAnimation));
}

TEST(SearchPlanner, MonotoneAnimationIsExactAndCheaperThanBruteForce) {
  const PlannerOptions options = Options(16, 9, 31, 6);
  const RenderRun run = Render(options, MonotoneAnimation, 11);
  const uint64_t traced = CheckFramesAndCountTraced(run, options);
  EXPECT_EQ(CountWrongPixels(run.frames, options, MonotoneAnimation), 0u);
  EXPECT_LT(traced, 31u * 16u * 9u / 2);
  ExpectMatchesReference(run, options, RenderReference(options, MonotoneAnimation));
}

// Section 4's pathological case: a one-pixel object moves diagonally one pixel per frame
// from (1,1) at frame 0 to (9,9) at frame 8, over a textured background.
Rgb MovingDot(int frame, int x, int y) {
  if (x == 1 + frame && y == 1 + frame) return {1.0f, 1.0f, 1.0f};
  return StaticAnimation(frame, x, y);
}

TEST(SearchPlanner, MovingOnePixelObjectIsLostBetweenBinEnds) {
  const PlannerOptions options = Options(12, 12, 9, 9);
  const RenderRun run = Render(options, MovingDot);
  // The path pixels (2,2) .. (8,8) hold background at both ends, so they are copied
  // and the dot vanishes from frames 1 .. 7: exactly one wrong pixel per inner frame.
  EXPECT_EQ(CountWrongPixels(run.frames, options, MovingDot), 7u);
  for (int f = 1; f <= 7; ++f) {
    EXPECT_NE(ValueAt(run.frames.at(f), 12, 1 + f, 1 + f), MovingDot(f, 1 + f, 1 + f)) << f;
    EXPECT_EQ(ValueAt(run.frames.at(f), 12, 1 + f, 1 + f), StaticAnimation(f, 1 + f, 1 + f)) << f;
  }
  // The start and end pixels differ at the ends and are searched correctly: (1,1) is
  // traced at 4, 2, 1; (9,9) at 4, 6, 7.
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 2u * 144u + 3u + 3u);
  ExpectMatchesReference(run, options, RenderReference(options, MovingDot));

  // Brute force sees the dot everywhere.
  const PlannerOptions bruteForce = Options(12, 12, 9, 2);
  EXPECT_EQ(CountWrongPixels(Render(bruteForce, MovingDot).frames, bruteForce, MovingDot), 0u);
}

// Pixel 0 drifts by 0.004 per frame; pixel 1 jumps by 0.5 at frame 3; the rest is still.
Rgb DriftAndJump(int frame, int x, int) {
  if (x == 0) return {0.5f + 0.004f * static_cast<float>(frame), 0.0f, 0.0f};
  if (x == 1) return {frame >= 3 ? 1.0f : 0.5f, 0.0f, 0.0f};
  return {0.25f, 0.0f, 0.0f};
}

TEST(SearchPlanner, ToleranceTreatsSmallDifferencesAsEqual) {
  // One bin [0, 4], 4 x 1 pixels: 8 end pixels. The jump is traced at 2 and 3 always.
  PlannerOptions options = Options(4, 1, 5, 5);
  options.tolerance = 0.02f;  // drift over the bin is 0.016: copied
  RenderRun run = Render(options, DriftAndJump);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 8u + 2u);
  for (int f = 1; f <= 3; ++f) EXPECT_EQ(ValueAt(run.frames.at(f), 4, 0, 0), DriftAndJump(0, 0, 0)) << f;
  EXPECT_EQ(CountWrongPixels(run.frames, options, DriftAndJump), 3u);  // the drift, copied from frame 0
  ExpectMatchesReference(run, options, RenderReference(options, DriftAndJump));

  options.tolerance = 0.01f;  // 0.016 over [0,4] differs: trace at 2; 0.008 halves are equal
  run = Render(options, DriftAndJump);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 8u + 2u + 1u);

  options.tolerance = 0;  // bitwise: the drift is traced at 2, 1 and 3
  run = Render(options, DriftAndJump);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 8u + 2u + 3u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, DriftAndJump), 0u);
}

TEST(SearchPlanner, LiveFramesBoundedByLiveBins) {
  PlannerOptions options = Options(8, 6, 300, 10);
  options.maxLiveBins = 2;
  RenderRun run = Render(options, MonotoneAnimation, 5);
  CheckFramesAndCountTraced(run, options);
  EXPECT_EQ(CountWrongPixels(run.frames, options, MonotoneAnimation), 0u);
  // Two bins of n frames each. (They share an end frame only when adjacent; once a
  // later bin finishes first, the two live bins are disjoint and hold 2n frames.)
  EXPECT_LE(run.maxLiveFrames, 20u);
  EXPECT_GE(run.maxLiveFrames, 10u);

  options.maxLiveBins = 1;
  run = Render(options, MonotoneAnimation, 6);
  CheckFramesAndCountTraced(run, options);
  EXPECT_LE(run.maxLiveFrames, 10u);
}

TEST(SearchPlanner, ManyTasksInFlightAcrossIntervalsAndBins) {
  PlannerOptions options = Options(16, 16, 33, 9);
  options.maxTaskPixels = 32;
  const RenderRun run = Render(options, MonotoneAnimation, 9);
  // Four bins' end frames alone are 5 frames of 8 tasks.
  EXPECT_GE(run.maxInFlightTasks, 40u);
  ExpectMatchesReference(run, options, RenderReference(options, MonotoneAnimation));
}

TEST(SearchPlanner, FramesFinishInBinOrderWithOneLiveBin) {
  PlannerOptions options = Options(4, 4, 25, 5);  // bins [0,4] [4,8] ... [20,24]
  options.maxLiveBins = 1;
  SearchPlanner planner(options);
  std::set<int> finished;
  std::vector<TraceTask> outstanding = planner.TakeReadyTasks();
  while (!outstanding.empty()) {
    const TraceTask task = outstanding.back();
    outstanding.pop_back();
    // A task of bin k (frames 4k+1 .. 4k+4, or frame 0) comes only after every frame
    // before the bin's left end has been handed out.
    const int binLeft = task.frame == 0 ? 0 : (task.frame - 1) / 4 * 4;
    for (int f = 0; f < binLeft; ++f) EXPECT_EQ(finished.count(f), 1u) << "task at " << task.frame << ", frame " << f;
    const std::vector<float> rgb = Trace(task, MonotoneAnimation, options.width);
    planner.OnResult(task.id, rgb.data(), rgb.size());
    for (const FinishedFrame& frame : planner.TakeFinishedFrames()) finished.insert(frame.frame);
    for (TraceTask& next : planner.TakeReadyTasks()) outstanding.push_back(std::move(next));
  }
  EXPECT_TRUE(planner.Done());
  EXPECT_EQ(finished.size(), 25u);
}

TEST(SearchPlanner, OnResultRejectsBadResultsAndIgnoresRedelivery) {
  PlannerOptions options = Options(3, 2, 3, 3);
  SearchPlanner planner(options);
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_EQ(tasks.size(), 2u);  // frames 0 and 2, 6 pixels each
  const TraceTask task = tasks[0];
  std::vector<float> rgb = Trace(task, StaticAnimation, options.width);

  EXPECT_THROW(planner.OnResult(0, rgb.data(), rgb.size()), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(999, rgb.data(), rgb.size()), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(task.id, rgb.data(), rgb.size() - 1), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(task.id, rgb.data(), rgb.size() + 3), std::invalid_argument);
  EXPECT_THROW(planner.OnResult(task.id, nullptr, rgb.size()), std::invalid_argument);
  std::vector<float> poisoned = rgb;
  poisoned[4] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(planner.OnResult(task.id, poisoned.data(), poisoned.size()), std::invalid_argument);
  poisoned[4] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(planner.OnResult(task.id, poisoned.data(), poisoned.size()), std::invalid_argument);
  EXPECT_EQ(planner.TracedPixels(), 0u);  // rejected results change nothing

  EXPECT_TRUE(planner.OnResult(task.id, rgb.data(), rgb.size()));
  EXPECT_FALSE(planner.OnResult(task.id, rgb.data(), rgb.size()));  // re-delivered: ignored
  EXPECT_FALSE(planner.OnResult(task.id, nullptr, 0));
  EXPECT_EQ(planner.TracedPixels(), 6u);

  const std::vector<float> last = Trace(tasks[1], StaticAnimation, options.width);
  EXPECT_TRUE(planner.OnResult(tasks[1].id, last.data(), last.size()));
  EXPECT_TRUE(planner.TakeReadyTasks().empty());
  EXPECT_EQ(planner.TakeFinishedFrames().size(), 3u);
  EXPECT_TRUE(planner.Done());
}

TEST(SearchPlanner, ErrorMessagesSayWhatWasExpected) {
  SearchPlanner planner(Options(3, 2, 3, 3));
  const TraceTask task = planner.TakeReadyTasks().at(0);
  const std::vector<float> rgb(5, 0.0f);
  try {
    planner.OnResult(task.id, rgb.data(), rgb.size());
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()),
              "result of task 1 (frame 0) has 5 floats; expected 18 (3 per pixel, 6 pixels)");
  }
  try {
    SearchPlanner(Options(3, 2, 3, 1));
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "PlannerOptions.binWidth is 1; expected >= 2 (2 traces every pixel)");
  }
}

TEST(SearchPlanner, BadOptionsThrow) {
  auto rejects = [](PlannerOptions options, const std::string& field) {
    try {
      SearchPlanner planner(options);
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(field), std::string::npos) << error.what();
      return;
    }
    ADD_FAILURE() << "accepted bad " << field;
  };
  const PlannerOptions good = Options(4, 4, 10, 4);
  PlannerOptions bad = good;
  bad.width = 0;
  rejects(bad, "width");
  bad = good;
  bad.height = -3;
  rejects(bad, "height");
  bad = good;
  bad.width = 70000;
  bad.height = 70000;
  rejects(bad, "width * height");
  bad = good;
  bad.frameCount = 0;
  rejects(bad, "frameCount");
  bad = good;
  bad.binWidth = 1;
  rejects(bad, "binWidth");
  bad = good;
  bad.maxTaskPixels = 0;
  rejects(bad, "maxTaskPixels");
  bad = good;
  bad.maxLiveBins = 0;
  rejects(bad, "maxLiveBins");
  bad = good;
  bad.tolerance = -0.1f;
  rejects(bad, "tolerance");
  bad = good;
  bad.tolerance = std::numeric_limits<float>::quiet_NaN();
  rejects(bad, "tolerance");
  EXPECT_NO_THROW(SearchPlanner{good});
}

TEST(SearchPlanner, ChunkingDoesNotChangeTheFrames) {
  PlannerOptions options = Options(9, 7, 14, 5);
  const Reference ref = RenderReference(options, MonotoneAnimation);
  for (uint32_t maxTaskPixels : {1u, 7u, 63u, 16384u}) {
    options.maxTaskPixels = maxTaskPixels;
    const RenderRun run = Render(options, MonotoneAnimation, maxTaskPixels);
    EXPECT_EQ(CheckFramesAndCountTraced(run, options), ref.tracedCount) << maxTaskPixels;
    ExpectMatchesReference(run, options, ref);
  }
}

// Piecewise-constant pixels from a small palette that change at random frames and may
// return to an earlier value, so equal ends with a change between (the paper's flaw)
// happen often: the planner must still agree with the sequential algorithm exactly.
Animation RandomFlickers(uint32_t seed, int frames, int width, int height) {
  std::mt19937 rng(seed);
  std::vector<Rgb> values(static_cast<size_t>(frames) * width * height);
  const float palette[] = {0.0f, 0.25f, 0.5f, 1.0f};
  for (int p = 0; p < width * height; ++p) {
    Rgb current = {palette[rng() % 4], 0.5f, 0.0f};
    const double changeRate = std::uniform_real_distribution<double>(0.0, 0.5)(rng);
    for (int f = 0; f < frames; ++f) {
      if (std::bernoulli_distribution(changeRate)(rng)) current[rng() % 3] = palette[rng() % 4];
      values[static_cast<size_t>(f) * width * height + p] = current;
    }
  }
  return [values, width, height](int frame, int x, int y) {
    return values[(static_cast<size_t>(frame) * height + y) * width + x];
  };
}

TEST(SearchPlanner, RandomizedAgreesWithSequentialAlgorithm) {
  std::mt19937 rng(424242);
  for (int round = 0; round < 150; ++round) {
    auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    PlannerOptions options = Options(pick(1, 9), pick(1, 7), pick(1, 40), pick(2, 14));
    options.maxTaskPixels = static_cast<uint32_t>(pick(1, 40));
    options.maxLiveBins = pick(1, 4);
    options.tolerance = pick(0, 1) ? 0.3f : 0.0f;
    const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
    const RenderRun run = Render(options, animation, rng());
    const Reference ref = RenderReference(options, animation);
    EXPECT_EQ(CheckFramesAndCountTraced(run, options), ref.tracedCount) << "round " << round;
    ExpectMatchesReference(run, options, ref);
    if (HasFailure()) {
      ADD_FAILURE() << "round " << round << ": " << options.width << "x" << options.height << " N "
                    << options.frameCount << " n " << options.binWidth << " chunk " << options.maxTaskPixels
                    << " bins " << options.maxLiveBins << " tolerance " << options.tolerance;
      return;
    }
  }
}

}  // namespace
}  // namespace tcfarm
