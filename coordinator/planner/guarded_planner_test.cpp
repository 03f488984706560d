#include "coordinator/planner/guarded_planner.h"
#include "coordinator/planner/auto_guarded_planner.h"
#include "coordinator/planner/bin_width_survey.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "coordinator/planner/planner.h"
#include "coordinator/planner/search_planner.h"
#include "coordinator/planner/planner_test_support.h"

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
  std::vector<TraceTask> emitted;  // in emission order
  size_t maxLiveFrames = 0;
  uint64_t traced = 0;
  uint64_t copied = 0;
};

// Drives a planner to the end, answering one randomly chosen outstanding task at a
// time, so results come back in an order unrelated to the order of emission.
// onEmit sees every task as it is taken; onAnswer every task just before its result goes in.
RenderRun Drive(Planner& planner, const PlannerOptions& options, const Animation& animation, uint32_t seed = 1,
                const std::function<void(const TraceTask&)>& onEmit = nullptr,
                const std::function<void(const TraceTask&)>& onAnswer = nullptr) {
  std::mt19937 rng(seed);
  std::vector<TraceTask> outstanding;
  std::set<uint64_t> ids;
  RenderRun run;
  for (;;) {
    for (TraceTask& task : planner.TakeReadyTasks()) {
      EXPECT_TRUE(ids.insert(task.id).second) << "task " << task.id << " emitted twice";
      EXPECT_LE(task.pixels.size(), options.maxTaskPixels);
      EXPECT_FALSE(task.pixels.empty());
      EXPECT_EQ(task.window, 0) << "guarded and search want no horizons";
      if (onEmit) onEmit(task);
      run.emitted.push_back(task);
      outstanding.push_back(std::move(task));
    }
    if (outstanding.empty()) break;
    std::swap(outstanding[std::uniform_int_distribution<size_t>(0, outstanding.size() - 1)(rng)], outstanding.back());
    const TraceTask task = std::move(outstanding.back());
    outstanding.pop_back();
    if (onAnswer) onAnswer(task);
    const std::vector<float> rgb = Trace(task, animation, options.width);
    EXPECT_TRUE(planner.OnResult(task.id, rgb.data(), rgb.size()));
    run.maxLiveFrames = std::max(run.maxLiveFrames, planner.LiveFrames());
    for (FinishedFrame& frame : planner.TakeFinishedFrames()) {
      const int number = frame.frame;
      EXPECT_TRUE(run.frames.emplace(number, std::move(frame)).second) << "frame " << number << " finished twice";
    }
  }
  EXPECT_TRUE(planner.Done()) << "the planner stalled with no task outstanding";
  run.traced = planner.TracedPixels();
  run.copied = planner.CopiedPixels();
  if (options.keptFrames.empty()) {
    EXPECT_EQ(run.traced + run.copied, PixelsPerFrame(options) * options.frameCount);
  }
  return run;
}

RenderRun RenderGuarded(const PlannerOptions& options, const Animation& animation, uint32_t seed = 1) {
  GuardedPlanner planner(options);
  return Drive(planner, options, animation, seed);
}

RenderRun RenderSearch(const PlannerOptions& options, const Animation& animation, uint32_t seed = 1) {
  SearchPlanner planner(options);
  return Drive(planner, options, animation, seed);
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
  EXPECT_EQ(traced, run.traced);
  return traced;
}

// The coarse raster written independently of CoarseGuard: the sample of tile (tx, ty).
int SampleCoordinate(int tileIndex, int tile, int extent) {
  return tileIndex * tile + std::min(tile / 2, extent - 1 - tileIndex * tile);
}

// The guarded algorithm written the obvious way: sequential, one pixel at a time. The
// planner must agree with it bit for bit, values and traced pixels.
struct Reference {
  std::vector<std::vector<Rgb>> values;  // [frame][pixel]
  std::vector<std::vector<uint8_t>> traced;
  uint64_t tracedCount = 0;
};

Reference RenderGuardedReference(const PlannerOptions& options, const Animation& animation) {
  const int width = options.width, height = options.height, pixels = width * height;
  const int frames = options.frameCount, n = options.binWidth, tile = options.coarseTile;
  const int tilesAcross = (width + tile - 1) / tile, tilesDown = (height + tile - 1) / tile;
  Reference ref;
  ref.values.assign(frames, std::vector<Rgb>(pixels));
  ref.traced.assign(frames, std::vector<uint8_t>(pixels, 0));
  auto trace = [&](int f, int p) {
    if (ref.traced[f][p]) return;  // an end frame's samples come with its full trace
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
  std::vector<int> sampleOfTile;
  std::vector<bool> isSample(pixels, false);
  for (int ty = 0; ty < tilesDown; ++ty) {
    for (int tx = 0; tx < tilesAcross; ++tx) {
      const int p = SampleCoordinate(ty, tile, height) * width + SampleCoordinate(tx, tile, width);
      sampleOfTile.push_back(p);
      isSample[p] = true;
    }
  }
  auto tileChanges = [&](int p, int l, int r) {
    const int sample = sampleOfTile[(p / width / tile) * tilesAcross + (p % width) / tile];
    for (int f = l; f < r; ++f) {
      if (!equal(ref.values[f][sample], ref.values[f + 1][sample])) return true;
    }
    return false;
  };
  std::function<void(int, int, int)> search = [&](int p, int l, int r) {
    if (r - l <= 1) return;
    if (equal(ref.values[l][p], ref.values[r][p]) && !tileChanges(p, l, r)) {
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
  for (int f = 0; f < frames; ++f) {
    for (int p : sampleOfTile) trace(f, p);
  }
  for (size_t b = 0; b + 1 < ends.size(); ++b) {
    for (int p = 0; p < pixels; ++p) {
      if (!isSample[p]) search(p, ends[b], ends[b + 1]);
    }
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
  EXPECT_EQ(run.traced, ref.tracedCount);
}

Rgb StaticAnimation(int, int x, int y) { return {0.1f * x, 0.2f * y, 0.3f}; }

Rgb NoisyAnimation(int frame, int x, int y) {
  // Unsigned products: they wrap by definition, where int products overflow (UBSan).
  const unsigned hash = static_cast<unsigned>(frame) * 73856093u ^ static_cast<unsigned>(x) * 19349663u ^
                        static_cast<unsigned>(y) * 83492791u;
  return {static_cast<float>(hash % 1000) / 1000.0f, static_cast<float>(frame), 0.0f};
}

// ---- the coarse raster ----

TEST(CoarseGuard, SamplesTheExistingPixelNearestEachTileCentre) {
  // 20 x 11 in 8 x 8 tiles: columns 0-7, 8-15, 16-19 (partial), rows 0-7, 8-10 (partial).
  CoarseGuard guard(20, 11, 8, 0.0f);
  EXPECT_EQ(guard.TileCount(), 6u);
  const std::vector<uint32_t> expected = {4 * 20 + 4,  4 * 20 + 12,  4 * 20 + 19,
                                          10 * 20 + 4, 10 * 20 + 12, 10 * 20 + 19};
  EXPECT_EQ(guard.Samples(), PixelSet::FromSortedIndices(expected));
  for (uint32_t tile = 0; tile < 6; ++tile) {
    EXPECT_EQ(guard.SampleOf(tile), expected[tile]) << tile;
    EXPECT_EQ(guard.TileOf(expected[tile]), tile) << tile;
  }
  EXPECT_EQ(guard.TileOf(0), 0u);
  EXPECT_EQ(guard.TileOf(7 * 20 + 15), 1u);
  EXPECT_EQ(guard.TileOf(8 * 20 + 16), 5u);
  EXPECT_EQ(guard.TileOf(10 * 20 + 19), 5u);
}

TEST(CoarseGuard, TileOfOneSamplesEveryPixelAndOnePixelImagesWork) {
  CoarseGuard everyPixel(5, 3, 1, 0.0f);
  EXPECT_EQ(everyPixel.Samples(), PixelSet::Full(15));
  CoarseGuard single(1, 1, 8, 0.0f);
  EXPECT_EQ(single.Samples(), PixelSet::Full(1));
  EXPECT_THROW(CoarseGuard(4, 4, 0, 0.0f), std::invalid_argument);
}

TEST(CoarseGuard, PixelsOfChangedTilesCoverWholeTilesOverTheInterval) {
  // 6 x 5 in 4 x 4 tiles: samples (2,2), (5,2), (2,4), (5,4). Frames 10 .. 13.
  CoarseGuard guard(6, 5, 4, 0.0f);
  std::vector<std::vector<float>> frames(4, std::vector<float>(30 * 3, 0.0f));
  frames[2][(2 * 6 + 5) * 3] = 1.0f;      // tile 1 changes 11 -> 12 and back 12 -> 13
  frames[1][(4 * 6 + 2) * 3 + 2] = 1.0f;  // tile 2 changes 10 -> 11 and back 11 -> 12
  frames[3][0] = 1.0f;                    // a non-sample pixel: the guard does not see it
  guard.IndexBin(7, 10, {frames[0].data(), frames[1].data(), frames[2].data(), frames[3].data()});
  EXPECT_EQ(guard.IndexedBins(), 1u);

  PixelSetBuilder tile1, tile2, both;
  for (uint32_t y = 0; y < 5; ++y) {
    for (uint32_t x = 0; x < 6; ++x) {
      const uint32_t p = y * 6 + x;
      if (x >= 4 && y < 4) tile1.Add(p);
      if (x < 4 && y >= 4) tile2.Add(p);
      if ((x >= 4 && y < 4) || (x < 4 && y >= 4)) both.Add(p);
    }
  }
  EXPECT_EQ(guard.PixelsOfChangedTiles(7, 10, 13), both.Build());  // ends equal, changes inside
  EXPECT_EQ(guard.PixelsOfChangedTiles(7, 12, 13), tile1.Build());
  EXPECT_EQ(guard.PixelsOfChangedTiles(7, 10, 11), tile2.Build());
  EXPECT_TRUE(guard.PixelsOfChangedTiles(7, 12, 12).empty());
  EXPECT_THROW(guard.PixelsOfChangedTiles(7, 9, 12), std::logic_error);
  EXPECT_THROW(guard.PixelsOfChangedTiles(3, 10, 12), std::logic_error);
  guard.ForgetBin(7);
  EXPECT_EQ(guard.IndexedBins(), 0u);
}

TEST(CoarseGuard, ToleranceAppliesToSamples) {
  CoarseGuard guard(2, 1, 2, 0.1f);  // one tile, sample (1, 0)
  std::vector<float> a(6, 0.5f), b(6, 0.5f), c(6, 0.5f);
  b[3] = 0.55f;  // within tolerance
  c[3] = 0.75f;  // beyond it
  guard.IndexBin(0, 0, {a.data(), b.data(), c.data()});
  EXPECT_TRUE(guard.PixelsOfChangedTiles(0, 0, 1).empty());
  EXPECT_EQ(guard.PixelsOfChangedTiles(0, 1, 2), PixelSet::Full(2));
}

// ---- the planner ----

// Section 4's pathological case, through the tile centres: a one-pixel object moves
// along the row of tile centres y = 4, 8 pixels per frame, from (4, 4) at frame 0 to
// (36, 4) at frame 4, over a textured background. 40 x 16: two rows of five tiles.
Rgb DotThroughTileCentres(int frame, int x, int y) {
  if (x == 4 + 8 * frame && y == 4) return {1.0f, 1.0f, 1.0f};
  return StaticAnimation(frame, x, y);
}

// A resumed guarded job: bins kept whole are skipped, the others (their coarse pass
// included) give the frames of an uninterrupted run, bit for bit.
TEST(GuardedPlanner, ResumedJobMatchesAnUninterruptedRun) {
  PlannerOptions options = Options(20, 12, 19, 4, 4);  // bins [0,3] [3,6] ... [15,18]
  const Animation animation = [](int f, int x, int y) {
    return Rgb{static_cast<float>(x == (f * 2) % 20 && y == 5), static_cast<float>((x + y) % 3), 0.0f};
  };
  const RenderRun full = RenderGuarded(options, animation);
  options.keptFrames.assign(19, false);
  for (int f = 0; f <= 7; ++f) options.keptFrames[f] = true;  // bins [0,3] and [3,6] whole, [6,9] partly
  const RenderRun resumed = RenderGuarded(options, animation);
  ASSERT_EQ(resumed.frames.size(), 13u);  // frames 6 .. 18
  for (const auto& [f, frame] : resumed.frames) {
    EXPECT_GE(f, 6);
    EXPECT_EQ(frame.rgb, full.frames.at(f).rgb) << "frame " << f;
    EXPECT_EQ(frame.traced, full.frames.at(f).traced) << "frame " << f;
  }
}

TEST(GuardedPlanner, MovingOnePixelObjectThroughTileCentresIsExact) {
  const PlannerOptions options = Options(40, 16, 5, 5);

  // search: (12,4), (20,4), (28,4) hold background at both ends and are copied wrongly
  // at frames 1, 2, 3. (4,4) is traced at 2 and 1, (36,4) at 2 and 3.
  const RenderRun search = RenderSearch(options, DotThroughTileCentres);
  EXPECT_EQ(CountWrongPixels(search.frames, options, DotThroughTileCentres), 3u);
  EXPECT_EQ(CheckFramesAndCountTraced(search, options), 2u * 640u + 4u);

  // guarded: ends 2 x 640; samples at frames 1, 2, 3: 3 x 10. Every tile of the top row
  // changes inside [0, 4], so their 5 x 63 other pixels are traced at 2; on [0, 2] tiles
  // 0, 1, 2 change (traced at 1), on [2, 4] tiles 2, 3, 4 (traced at 3). The bottom row
  // never changes and is copied.
  const RenderRun guarded = RenderGuarded(options, DotThroughTileCentres);
  EXPECT_EQ(CountWrongPixels(guarded.frames, options, DotThroughTileCentres), 0u);
  const uint64_t traced = CheckFramesAndCountTraced(guarded, options);
  EXPECT_EQ(traced, 2u * 640u + 3u * 10u + 315u + 189u + 189u);
  EXPECT_EQ(traced - (2u * 640u + 4u), 719u);  // what exactness costs over search here
  EXPECT_EQ(guarded.frames.at(2).tracedCount, 10u + 315u);
  EXPECT_EQ(guarded.frames.at(1).tracedCount, 10u + 189u);
  EXPECT_EQ(guarded.frames.at(3).tracedCount, 10u + 189u);
  ExpectMatchesReference(guarded, options, RenderGuardedReference(options, DotThroughTileCentres));
}

// A one-pixel-high bar 8 pixels long slides one pixel per frame along the row of tile
// centres: every frame it covers exactly one sample, yet most of its pixels are not
// samples. Each pixel it passes changes twice between equal bin ends.
Rgb SlidingBar(int frame, int x, int y) {
  if (y == 4 && x >= 2 + frame && x <= 9 + frame) return {1.0f, 0.0f, 0.0f};
  return StaticAnimation(frame, x, y);
}

TEST(GuardedPlanner, ObjectCoveringATileCentreEveryFrameIsExact) {
  const PlannerOptions options = Options(48, 8, 17, 17);
  const RenderRun search = RenderSearch(options, SlidingBar);
  EXPECT_GT(CountWrongPixels(search.frames, options, SlidingBar), 0u);
  const RenderRun guarded = RenderGuarded(options, SlidingBar, 5);
  EXPECT_EQ(CountWrongPixels(guarded.frames, options, SlidingBar), 0u);
  CheckFramesAndCountTraced(guarded, options);
  ExpectMatchesReference(guarded, options, RenderGuardedReference(options, SlidingBar));
  EXPECT_LT(guarded.traced, 17u * 48u * 8u);  // still cheaper than brute force
}

TEST(GuardedPlanner, StaticSceneTracesBinEndsAndCoarseSamplesOnly) {
  // N = 10, n = 4: bins [0,3] [3,6] [6,9]; ends 0, 3, 6, 9 in full (4 x 220), and the
  // 6 samples of 20 x 11 at each of the 6 inner frames.
  const PlannerOptions options = Options(20, 11, 10, 4);
  const RenderRun run = RenderGuarded(options, StaticAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 4u * 220u + 6u * 6u);
  const PixelSet samples = CoarseGuard(20, 11, 8, 0.0f).Samples();
  for (int f : {1, 2, 4, 5, 7, 8}) {
    const FinishedFrame& frame = run.frames.at(f);
    EXPECT_EQ(frame.tracedCount, 6u) << f;
    samples.ForEach([&](uint32_t p) { EXPECT_EQ(frame.traced[p], 1) << "frame " << f << " pixel " << p; });
  }
  EXPECT_EQ(CountWrongPixels(run.frames, options, StaticAnimation), 0u);
  ExpectMatchesReference(run, options, RenderGuardedReference(options, StaticAnimation));
}

TEST(GuardedPlanner, BinWidthTwoIsBruteForce) {
  const PlannerOptions options = Options(19, 10, 7, 2);
  const RenderRun run = RenderGuarded(options, NoisyAnimation, 3);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 7u * 190u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, NoisyAnimation), 0u);
  const RenderRun brute = RenderSearch(options, NoisyAnimation, 4);
  for (int f = 0; f < 7; ++f) EXPECT_EQ(run.frames.at(f).rgb, brute.frames.at(f).rgb) << f;
}

TEST(GuardedPlanner, CoarseTileOneIsBruteForce) {
  const PlannerOptions options = Options(7, 5, 9, 5, 1);
  const RenderRun run = RenderGuarded(options, NoisyAnimation);
  EXPECT_EQ(CheckFramesAndCountTraced(run, options), 9u * 35u);
  EXPECT_EQ(CountWrongPixels(run.frames, options, NoisyAnimation), 0u);
}

TEST(GuardedPlanner, SingleFrameAndTwoFrames) {
  for (int frames : {1, 2}) {
    const PlannerOptions options = Options(9, 9, frames, 8);
    const RenderRun run = RenderGuarded(options, NoisyAnimation);
    EXPECT_EQ(CheckFramesAndCountTraced(run, options), static_cast<uint64_t>(frames) * 81u);
    EXPECT_EQ(CountWrongPixels(run.frames, options, NoisyAnimation), 0u);
  }
}

TEST(GuardedPlanner, CoarsePassCompletesBeforeTheBinIsSearched) {
  // 24 x 16 in 8 x 8 tiles: 6 samples. Bins [0,6] [6,12] [12,18]; chunks of 2 pixels
  // split each coarse pass into 3 tasks.
  PlannerOptions options = Options(24, 16, 19, 7);
  options.maxTaskPixels = 2;
  options.maxLiveBins = 2;
  const PixelSet samples = CoarseGuard(24, 16, 8, 0.0f).Samples();
  auto binOf = [](int frame) { return (frame - 1) / 6; };  // of an inner frame
  auto isInner = [](int frame) { return frame % 6 != 0; };
  std::map<int, int> coarseOutstanding;  // per bin: coarse tasks emitted, result not yet in
  std::map<int, int> coarseEmitted;
  auto onEmit = [&](const TraceTask& task) {
    if (!isInner(task.frame)) return;
    const bool coarse = task.pixels.Intersection(samples) == task.pixels;
    if (coarse) {
      ++coarseOutstanding[binOf(task.frame)];
      ++coarseEmitted[binOf(task.frame)];
      return;
    }
    EXPECT_TRUE(task.pixels.Intersection(samples).empty()) << "the search traces a sample at " << task.frame;
    EXPECT_EQ(coarseEmitted[binOf(task.frame)], 5 * 3) << "bin " << binOf(task.frame) << " searched early";
    EXPECT_EQ(coarseOutstanding[binOf(task.frame)], 0) << "bin " << binOf(task.frame) << " searched early";
  };
  auto onAnswer = [&](const TraceTask& task) {
    if (isInner(task.frame) && task.pixels.Intersection(samples) == task.pixels) --coarseOutstanding[binOf(task.frame)];
  };
  GuardedPlanner planner(options);
  const RenderRun run = Drive(planner, options, SlidingBar, 7, onEmit, onAnswer);
  EXPECT_EQ(coarseEmitted.size(), 3u);
  // One task per chunk of one frame: coarse passes of different frames are independent.
  std::set<int> coarseFrames;
  for (const TraceTask& task : run.emitted) {
    if (isInner(task.frame) && task.pixels.Intersection(samples) == task.pixels) coarseFrames.insert(task.frame);
  }
  EXPECT_EQ(coarseFrames.size(), 15u);
  ExpectMatchesReference(run, options, RenderGuardedReference(options, SlidingBar));
}

TEST(GuardedPlanner, LiveFramesBoundedByLiveBins) {
  PlannerOptions options = Options(17, 9, 300, 10, 4);
  options.maxLiveBins = 2;
  const RenderRun run = RenderGuarded(options, SlidingBar, 5);
  CheckFramesAndCountTraced(run, options);
  EXPECT_LE(run.maxLiveFrames, 20u);
}

TEST(GuardedPlanner, BadCoarseTileThrows) {
  PlannerOptions options = Options(8, 8, 4, 4, 0);
  try {
    GuardedPlanner planner(options);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "PlannerOptions.coarseTile is 0; expected >= 1 (1 samples every pixel)");
  }
  options.coarseTile = 8;
  options.binWidth = 1;
  EXPECT_THROW(GuardedPlanner{options}, std::invalid_argument);
  options.binWidth = 4;
  options.width = 0;
  EXPECT_THROW(GuardedPlanner{options}, std::invalid_argument);
}

TEST(GuardedPlanner, HorizonsAreIgnoredAndRedeliveryIsReported) {
  GuardedPlanner planner(Options(4, 4, 3, 3, 2));
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_FALSE(tasks.empty());
  const TraceTask task = tasks.front();
  const std::vector<float> rgb = Trace(task, StaticAnimation, 4);
  const std::vector<int32_t> horizons(task.pixels.size(), 0);  // nonsense, but nobody asked
  EXPECT_TRUE(planner.OnResult(task.id, rgb.data(), rgb.size(), horizons.data(), horizons.size()));
  EXPECT_FALSE(planner.OnResult(task.id, rgb.data(), rgb.size()));
  EXPECT_THROW(planner.OnResult(999, rgb.data(), rgb.size()), std::invalid_argument);
}

// Piecewise-constant pixels from a small palette that change at random frames and may
// return to an earlier value, so equal ends with a change between happen often.
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

// Flicker in which a pixel changes only at frames where its tile's sample changes: at a
// tile's change, every pixel of the tile draws a new palette value (perhaps its old
// one) and the sample surely changes. Values still return to earlier ones, so the
// search is often wrong; the guard sees every change.
Animation TileAlignedFlickers(uint32_t seed, int frames, int width, int height, int tile) {
  std::mt19937 rng(seed);
  const int tilesAcross = (width + tile - 1) / tile, tilesDown = (height + tile - 1) / tile;
  const float palette[] = {0.0f, 0.25f, 0.5f, 1.0f};
  std::vector<Rgb> values(static_cast<size_t>(frames) * width * height);
  auto at = [&](int f, int x, int y) -> Rgb& { return values[(static_cast<size_t>(f) * height + y) * width + x]; };
  for (int ty = 0; ty < tilesDown; ++ty) {
    for (int tx = 0; tx < tilesAcross; ++tx) {
      const int sx = SampleCoordinate(tx, tile, width), sy = SampleCoordinate(ty, tile, height);
      const double changeRate = std::uniform_real_distribution<double>(0.0, 0.6)(rng);
      for (int f = 0; f < frames; ++f) {
        const bool change = f == 0 || std::bernoulli_distribution(changeRate)(rng);
        for (int y = ty * tile; y < std::min((ty + 1) * tile, height); ++y) {
          for (int x = tx * tile; x < std::min((tx + 1) * tile, width); ++x) {
            if (!change) {
              at(f, x, y) = at(f - 1, x, y);
              continue;
            }
            Rgb value = {palette[rng() % 4], palette[rng() % 4], 0.0f};
            if (f > 0 && x == sx && y == sy && value == at(f - 1, x, y)) value[2] = 1.0f - at(f - 1, x, y)[2];
            at(f, x, y) = value;
          }
        }
      }
    }
  }
  return [values, width, height](int frame, int x, int y) {
    return values[(static_cast<size_t>(frame) * height + y) * width + x];
  };
}

TEST(GuardedPlanner, RandomizedAgreesWithSequentialAlgorithm) {
  std::mt19937 rng(777);
  for (int round = 0; round < 120; ++round) {
    auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    PlannerOptions options = Options(pick(1, 20), pick(1, 13), pick(1, 30), pick(2, 12), pick(1, 6));
    options.maxTaskPixels = static_cast<uint32_t>(pick(1, 40));
    options.maxLiveBins = pick(1, 4);
    options.tolerance = pick(0, 1) ? 0.3f : 0.0f;
    const Animation animation = RandomFlickers(rng(), options.frameCount, options.width, options.height);
    const RenderRun run = RenderGuarded(options, animation, rng());
    CheckFramesAndCountTraced(run, options);
    ExpectMatchesReference(run, options, RenderGuardedReference(options, animation));
    if (HasFailure()) {
      ADD_FAILURE() << "round " << round << ": " << options.width << "x" << options.height << " N "
                    << options.frameCount << " n " << options.binWidth << " tile " << options.coarseTile
                    << " chunk " << options.maxTaskPixels << " bins " << options.maxLiveBins << " tolerance "
                    << options.tolerance;
      return;
    }
  }
}

TEST(GuardedPlanner, RandomizedTileAlignedChangesNeverWorseThanSearch) {
  std::mt19937 rng(31337);
  uint64_t searchWrongTotal = 0;
  for (int round = 0; round < 80; ++round) {
    auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    PlannerOptions options = Options(pick(1, 24), pick(1, 17), pick(1, 33), pick(2, 17), pick(2, 8));
    options.maxTaskPixels = static_cast<uint32_t>(pick(1, 64));
    options.maxLiveBins = pick(1, 3);
    options.tolerance = pick(0, 1) ? 0.1f : 0.0f;  // below the palette's steps
    const Animation animation =
        TileAlignedFlickers(rng(), options.frameCount, options.width, options.height, options.coarseTile);
    const uint32_t seed = rng();
    const uint64_t searchWrong = CountWrongPixels(RenderSearch(options, animation, seed).frames, options, animation);
    const RenderRun guarded = RenderGuarded(options, animation, seed);
    const uint64_t guardedWrong = CountWrongPixels(guarded.frames, options, animation);
    EXPECT_LE(guardedWrong, searchWrong) << "round " << round;
    EXPECT_EQ(guardedWrong, 0u) << "round " << round;  // the guard sees every change
    ExpectMatchesReference(guarded, options, RenderGuardedReference(options, animation));
    searchWrongTotal += searchWrong;
    if (HasFailure()) {
      ADD_FAILURE() << "round " << round << ": " << options.width << "x" << options.height << " N "
                    << options.frameCount << " n " << options.binWidth << " tile " << options.coarseTile;
      return;
    }
  }
  EXPECT_GT(searchWrongTotal, 0u) << "the animations never catch the search out; the test proves nothing";
}

// ---- the interface ----

// --- auto: guarded with a bin width chosen by a coarse survey ---

// A survey of `frames` frames of a w x h image in 8-pixel tiles, from an animation.
CoarseSurvey SurveyOf(int width, int height, int frames, const Animation& animation) {
  CoarseSurvey survey;
  survey.width = width;
  survey.height = height;
  const CoarseGuard guard(width, height, 8, 0.0f);
  for (int f = 0; f < frames; ++f) {
    TraceTask task{1, f, guard.Samples(), 0};
    survey.samples.push_back(Trace(task, animation, width));
  }
  return survey;
}

TEST(BinWidthSurvey, StaticSequenceTracesBinEndsAndSamplesOnly) {
  // 16 x 16, 2 x 2 tiles, 9 frames, n = 5: ends 0, 4, 8 in full, samples of 6 inner frames.
  const CoarseSurvey survey = SurveyOf(16, 16, 9, StaticAnimation);
  EXPECT_DOUBLE_EQ(PredictGuardedTracedShare(survey, 5), (3.0 * 256 + 6.0 * 4) / (9.0 * 256));
  // Nothing changes: one bin over all 9 frames traces least (two ends).
  EXPECT_EQ(ChooseGuardedBinWidth(survey, 16).binWidth, 9);
}

TEST(BinWidthSurvey, PredictionEqualsGuardedWhenTilesChangeAsAWhole) {
  // Whole tiles flicker at random frames: each tile's sample stands for its pixels, so
  // the prediction is exactly what GuardedPlanner traces.
  auto tileFlicker = [](int frame, int x, int y) {
    const uint32_t tile = static_cast<uint32_t>((y / 8) * 4 + x / 8);
    const uint32_t hash = (tile * 2654435761u) ^ (static_cast<uint32_t>(frame / 3) * 40503u);
    return Rgb{float((hash >> 7) % 3), 0.5f, 0.25f};
  };
  const PlannerOptions base = Options(32, 24, 13, 2);
  const CoarseSurvey survey = SurveyOf(32, 24, 13, tileFlicker);
  for (int width : {2, 3, 5, 7, 13}) {
    PlannerOptions options = base;
    options.binWidth = width;
    const RenderRun run = RenderGuarded(options, tileFlicker);
    EXPECT_DOUBLE_EQ(PredictGuardedTracedShare(survey, width),
                     double(run.traced) / (PixelsPerFrame(options) * options.frameCount))
        << "width " << width;
  }
}

TEST(BinWidthSurvey, ChoosesANarrowBinWhenChangesAreDenseInTime) {
  // Every tile changes every frame: wide bins trace their middles anyway and add nothing;
  // pixels that change once in a long while favour wide bins.
  const CoarseSurvey busy = SurveyOf(32, 32, 17, NoisyAnimation);
  const BinWidthChoice choice = ChooseGuardedBinWidth(busy, 16);
  EXPECT_EQ(choice.predicted.size(), 15u);
  EXPECT_EQ(choice.binWidth, 2);
  auto rare = [](int frame, int x, int y) { return Rgb{float(frame / 12 + (x + y) % 2), 0, 0}; };
  EXPECT_GE(ChooseGuardedBinWidth(SurveyOf(32, 32, 37, rare), 16).binWidth, 6);
}

TEST(BinWidthSurvey, BadSurveysAreRefusedWithWhatWasExpected) {
  CoarseSurvey survey = SurveyOf(16, 16, 3, StaticAnimation);
  survey.samples[1].pop_back();
  try {
    PredictGuardedTracedShare(survey, 2);
    FAIL() << "a short frame was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("frame 1 holds 11 floats; expected 12"), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(PredictGuardedTracedShare(SurveyOf(16, 16, 3, StaticAnimation), 1), std::invalid_argument);
}

TEST(AutoGuardedPlanner, SurveysThenRendersExactlyAsGuardedWithTheChosenWidth) {
  auto rare = [](int frame, int x, int y) { return Rgb{float(frame / 7 + (x / 8 + y / 8) % 2), 0, 0}; };
  PlannerOptions options = Options(40, 24, 30, 16);
  AutoGuardedPlanner planner(options);
  size_t surveyTasks = 0;
  const RenderRun run = Drive(planner, options, rare, 3, [&](const TraceTask& task) {
    if (planner.ChosenBinWidth() == 0) {
      ++surveyTasks;
      EXPECT_EQ(task.pixels.size(), CoarseGuard(40, 24, 8, 0.0f).Samples().size());
    }
  });
  EXPECT_EQ(surveyTasks, static_cast<size_t>(planner.SurveyedFrames()));
  EXPECT_EQ(planner.SurveyedFrames(), 30);  // min(frames, 3 * 15 + 1)
  const int chosen = planner.ChosenBinWidth();
  ASSERT_GE(chosen, 2);
  EXPECT_EQ(planner.Predictions().size(), 15u);
  // The same frames, pixel for pixel and traced for traced, as guarded run with that width:
  // the survey's samples became its coarse pass, none traced twice inside bins.
  PlannerOptions fixed = options;
  fixed.binWidth = chosen;
  const RenderRun guarded = RenderGuarded(fixed, rare);
  EXPECT_EQ(run.traced, guarded.traced);
  for (int f = 0; f < options.frameCount; ++f) {
    EXPECT_EQ(run.frames.at(f).rgb, guarded.frames.at(f).rgb) << "frame " << f;
    EXPECT_EQ(run.frames.at(f).traced, guarded.frames.at(f).traced) << "frame " << f;
  }
  EXPECT_EQ(CountWrongPixels(run.frames, options, rare), 0u);
}

TEST(AutoGuardedPlanner, RejectsUnknownIdsAndIgnoresRedeliveredSurveys) {
  PlannerOptions options = Options(16, 16, 5, 4);
  AutoGuardedPlanner planner(options);
  std::vector<TraceTask> tasks = planner.TakeReadyTasks();
  ASSERT_EQ(tasks.size(), 5u);
  std::vector<float> rgb = Trace(tasks[0], StaticAnimation, 16);
  EXPECT_THROW(planner.OnResult(7, rgb.data(), rgb.size()), std::invalid_argument);  // not issued yet
  EXPECT_THROW(planner.OnResult(tasks[0].id, rgb.data(), rgb.size() - 1), std::invalid_argument);
  EXPECT_TRUE(planner.OnResult(tasks[0].id, rgb.data(), rgb.size()));
  EXPECT_FALSE(planner.OnResult(tasks[0].id, rgb.data(), rgb.size()));
  EXPECT_EQ(planner.ChosenBinWidth(), 0);
  EXPECT_FALSE(planner.Done());
}

TEST(Planner, StrategiesByName) {
  for (const char* name : {"brute", "search", "guarded", "exact", "auto"}) {
    const auto strategy = StrategyFromString(name);
    ASSERT_TRUE(strategy.has_value()) << name;
    EXPECT_EQ(StrategyName(*strategy), name);
  }
  EXPECT_EQ(kDefaultStrategy, Strategy::kSearch);
  EXPECT_FALSE(StrategyFromString("").has_value());
  EXPECT_FALSE(StrategyFromString("Search").has_value());
  EXPECT_THROW(MakePlanner(Strategy::kAuto, Options(12, 9, 9, 5, 4)), std::invalid_argument);
}

// auto's one rule: exact with segments cut by the cost model when only shapes move, else
// guarded surveyed up to its widest bin; the others run as asked, brute with bins of 2.
TEST(Planner, ResolveStrategy) {
  constexpr uint64_t kPixels = 640 * 480;
  const ResolvedStrategy still = ResolveStrategy(Strategy::kAuto, 10, 60, false, 4, kPixels);
  EXPECT_EQ(still.strategy, Strategy::kExact);
  EXPECT_EQ(still.binWidth, 60);  // one segment: the frames' pixels keep 4 workers busy
  ASSERT_TRUE(still.segments.has_value());
  EXPECT_EQ(still.segments->segments, 1);
  EXPECT_FALSE(still.surveyBinWidth);
  EXPECT_NE(still.reason.find("1 segment of 60 frames for 4 workers"), std::string::npos) << still.reason;
  const ResolvedStrategy moving = ResolveStrategy(Strategy::kAuto, 10, 60, true, 4, kPixels);
  EXPECT_EQ(moving.strategy, Strategy::kGuarded);
  EXPECT_EQ(moving.binWidth, kAutoWidestBin);
  EXPECT_TRUE(moving.surveyBinWidth);
  for (bool moves : {false, true}) {  // one frame: nothing to reuse
    const ResolvedStrategy one = ResolveStrategy(Strategy::kAuto, 10, 1, moves, 4, kPixels);
    EXPECT_EQ(one.strategy, Strategy::kBrute);
    EXPECT_EQ(one.binWidth, 2);
  }
  // Prices at which a segment costs more than brute force: brute, and the reason says why.
  const ResolvedStrategy dear = ResolveStrategy(Strategy::kAuto, 10, 24, false, 1, kPixels, {3.0, 0.9});
  EXPECT_EQ(dear.strategy, Strategy::kBrute) << dear.reason;
  EXPECT_NE(dear.reason.find("at least 0.95"), std::string::npos) << dear.reason;
  const ResolvedStrategy cheap = ResolveStrategy(Strategy::kAuto, 10, 24, false, 1, kPixels, {3.0, 0.5});
  EXPECT_EQ(cheap.strategy, Strategy::kExact) << cheap.reason;
  EXPECT_EQ(ResolveStrategy(Strategy::kBrute, 10, 60, true, 4, kPixels).binWidth, 2);
  const ResolvedStrategy asked = ResolveStrategy(Strategy::kSearch, 7, 60, true, 4, kPixels);
  EXPECT_EQ(asked.strategy, Strategy::kSearch);
  EXPECT_EQ(asked.binWidth, 7);
}

// auto's exact segments: as few as keep the workers busy, never more than the CPU budget
// allows. Large frames spread over any farm, so they stay in one segment; small ones
// cannot, and a long sequence of them is cut into more segments, its CPU cost within
// kExtraCostBudget of one segment's.
TEST(Planner, SegmentsComeFromTheCostModelNotTheFarmSize) {
  constexpr uint64_t kLarge = 640 * 480, kSmall = 64 * 48;
  for (int workers : {1, 4, 16}) {
    EXPECT_EQ(PlanSegments(60, workers, kLarge).segments, 1) << workers;
    EXPECT_EQ(PlanSegments(600, workers, kLarge).segments, 1) << workers;
  }
  EXPECT_EQ(PlanSegments(60, 64, kLarge).segments, 1);  // any cut of 60 frames costs too much
  // More workers than a frame's tasks: a long sequence is cut, within the budget.
  const SegmentPlan wide = PlanSegments(600, 64, kLarge);
  EXPECT_GT(wide.segments, 1);
  EXPECT_LE(wide.predictedRelativeCost, PlanSegments(600, 1, kLarge).predictedRelativeCost * (1 + kExtraCostBudget));
  const SegmentPlan one = PlanSegments(600, 1, kSmall);
  EXPECT_EQ(one.segments, 1);
  const SegmentPlan many = PlanSegments(600, 64, kSmall);
  EXPECT_GT(many.segments, 1);
  EXPECT_EQ(many.length, (600 + many.segments - 1) / many.segments);
  EXPECT_LE(many.predictedRelativeCost, one.predictedRelativeCost * (1 + kExtraCostBudget));
  EXPECT_GT(many.predictedParallelism, one.predictedParallelism);
  EXPECT_EQ(PlanSegments(60, 64, kSmall).segments, 1);  // a short one: any cut costs too much
  EXPECT_LT(PlanSegments(600, 64, kSmall, SegmentPrices{10.0, 0.3}).segments, many.segments);  // dearer starts
  const SegmentPlan back = SegmentPlan::FromJson(many.ToJson());
  EXPECT_EQ(back.segments, many.segments);
  EXPECT_EQ(back.length, many.length);
  EXPECT_DOUBLE_EQ(back.predictedParallelism, many.predictedParallelism);
}

TEST(Planner, MakePlannerBuildsEachStrategy) {
  PlannerOptions options = Options(12, 9, 9, 5, 4);
  const Animation animation = SlidingBar;
  for (Strategy strategy : {Strategy::kBrute, Strategy::kSearch, Strategy::kGuarded}) {
    std::unique_ptr<Planner> planner = MakePlanner(strategy, options);
    const RenderRun run = Drive(*planner, options, animation, 2);
    const uint64_t traced = CheckFramesAndCountTraced(run, options);
    if (strategy == Strategy::kBrute) {
      EXPECT_EQ(traced, 9u * 108u);
      EXPECT_EQ(CountWrongPixels(run.frames, options, animation), 0u);
    }
    if (strategy == Strategy::kGuarded) {
      ExpectMatchesReference(run, options, RenderGuardedReference(options, animation));
    }
  }
  options.binWidth = 1;  // brute ignores the bin width
  EXPECT_NO_THROW(MakePlanner(Strategy::kBrute, options));
  EXPECT_THROW(MakePlanner(Strategy::kSearch, options), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm
