#include "proto/frame/sequence_analysis.h"

#include <gtest/gtest.h>

#include <limits>

#include <cstring>
#include <numeric>
#include <random>
#include <stdexcept>

namespace tcfarm {
namespace {

Image Flat(int width, int height, float value) {
  return Image{width, height, std::vector<float>(static_cast<size_t>(width) * height * 3, value)};
}

void SetPixel(Image* image, int x, int y, float value) {
  size_t pixel = static_cast<size_t>(y) * image->width + x;
  for (int c = 0; c < 3; ++c) image->rgb[3 * pixel + c] = value;
}

SequenceAnalysis Analyze(const std::vector<Image>& frames) {
  SequenceAnalyzer analyzer;
  for (const Image& frame : frames) analyzer.Add(frame);
  return analyzer.Finish();
}

double Sum(const std::vector<double>& values) {
  return std::accumulate(values.begin(), values.end(), 0.0);
}

// The change mask is bitwise, as the farm copies bits: -0 is a change from +0, and a NaN
// with the same bits is no change.
TEST(SequenceAnalysisTest, ChangeMaskComparesBits) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  SequenceAnalyzer analyzer;
  std::vector<uint8_t> unchanged;
  analyzer.Add(Image{3, 1, {0.0f, 0, 0, nan, 1, 1, 0.5f, 0.5f, 0.5f}}, &unchanged);
  EXPECT_EQ(unchanged, (std::vector<uint8_t>{1, 1, 1}));  // nothing to change from
  analyzer.Add(Image{3, 1, {-0.0f, 0, 0, nan, 1, 1, 0.5f, 0.5f, 0.75f}}, &unchanged);
  EXPECT_EQ(unchanged, (std::vector<uint8_t>{0, 1, 0}));
  EXPECT_NEAR(analyzer.frameToFrame().Mean(), 1.0 / 3.0, 1e-12);
}

TEST(SequenceAnalysisTest, StaticSequenceIsOneFullEventPerPixel) {
  const int frames = 7;
  SequenceAnalysis analysis = Analyze(std::vector<Image>(frames, Flat(4, 3, 0.5f)));
  EXPECT_EQ(analysis.frames, frames);
  EXPECT_EQ(analysis.width, 4);
  EXPECT_EQ(analysis.height, 3);
  ASSERT_EQ(analysis.eventsByDuration.size(), size_t(frames + 1));
  for (int duration = 0; duration < frames; ++duration) {
    EXPECT_EQ(analysis.eventsByDuration[duration], 0u) << duration;
  }
  EXPECT_EQ(analysis.eventsByDuration[frames], 12u);
  EXPECT_EQ(analysis.eventCount, 12u);
  EXPECT_DOUBLE_EQ(analysis.volumeShareByDuration[frames], 1.0);
  EXPECT_DOUBLE_EQ(analysis.meanEventDuration, frames);
  EXPECT_DOUBLE_EQ(analysis.eventDurationStdDev, 0.0);
  EXPECT_EQ(analysis.frameToFrame.count, size_t(frames - 1));
  EXPECT_DOUBLE_EQ(analysis.frameToFrame.Mean(), 1.0);
  EXPECT_DOUBLE_EQ(analysis.longTerm.min, 1.0);
  EXPECT_DOUBLE_EQ(analysis.d, 0.0);
  EXPECT_DOUBLE_EQ(analysis.ChangedPixelShare(), 0.0);
  EXPECT_EQ(analysis.changeMask, std::vector<uint8_t>(12, 0));
}

TEST(SequenceAnalysisTest, PixelFlippingEveryFrameHasOneFrameEvents) {
  // 2x1 image: pixel 0 flips every frame, pixel 1 stays. 5 frames.
  std::vector<Image> frames;
  for (int f = 0; f < 5; ++f) {
    Image image = Flat(2, 1, 0.25f);
    SetPixel(&image, 0, 0, f % 2 ? 1.0f : 0.0f);
    frames.push_back(image);
  }
  SequenceAnalysis analysis = Analyze(frames);
  EXPECT_EQ(analysis.eventsByDuration, (std::vector<uint64_t>{0, 5, 0, 0, 0, 1}));
  EXPECT_EQ(analysis.eventCount, 6u);
  EXPECT_DOUBLE_EQ(analysis.volumeShareByDuration[1], 0.5);
  EXPECT_DOUBLE_EQ(analysis.volumeShareByDuration[5], 0.5);
  EXPECT_DOUBLE_EQ(analysis.meanEventDuration, 10.0 / 6);
  // Durations 1 x5 and 5 x1 around the mean 5/3: sqrt((5 (2/3)^2 + (10/3)^2) / 6).
  EXPECT_NEAR(analysis.eventDurationStdDev, std::sqrt((5 * 4.0 / 9 + 100.0 / 9) / 6), 1e-12);
  EXPECT_EQ(analysis.frameToFrameByFrame, (std::vector<double>{0.5, 0.5, 0.5, 0.5}));
  // Pixel 0 equals the first frame's value at even frames only.
  EXPECT_EQ(analysis.longTermByFrame, (std::vector<double>{0.5, 1.0, 0.5, 1.0}));
  EXPECT_DOUBLE_EQ(analysis.d, 0.5);
  EXPECT_EQ(analysis.changeMask, (std::vector<uint8_t>{1, 0}));
  EXPECT_DOUBLE_EQ(analysis.ChangedPixelShare(), 0.5);
}

TEST(SequenceAnalysisTest, PixelChangingOnceSplitsIntoTwoEvents) {
  const int frames = 10, changeAt = 3;  // frames 0..2 one value, 3..9 another
  std::vector<Image> sequence;
  for (int f = 0; f < frames; ++f) {
    Image image = Flat(3, 2, 0.1f);
    if (f >= changeAt) SetPixel(&image, 2, 1, 0.9f);
    sequence.push_back(image);
  }
  SequenceAnalysis analysis = Analyze(sequence);
  std::vector<uint64_t> expected(frames + 1, 0);
  expected[changeAt] = 1;
  expected[frames - changeAt] = 1;
  expected[frames] = 5;
  EXPECT_EQ(analysis.eventsByDuration, expected);
  EXPECT_NEAR(Sum(analysis.volumeShareByDuration), 1.0, 1e-12);
  EXPECT_EQ(analysis.changeMask, (std::vector<uint8_t>{0, 0, 0, 0, 0, 1}));
  ASSERT_EQ(analysis.longTermByFrame.size(), size_t(frames - 1));
  for (int f = 1; f < frames; ++f) {
    EXPECT_DOUBLE_EQ(analysis.longTermByFrame[f - 1], f < changeAt ? 1.0 : 5.0 / 6) << f;
  }
  EXPECT_DOUBLE_EQ(analysis.frameToFrame.min, 5.0 / 6);
  EXPECT_DOUBLE_EQ(analysis.frameToFrame.max, 1.0);
  EXPECT_NEAR(analysis.d, (1.0 / 6) / (frames - 1), 1e-15);
}

TEST(SequenceAnalysisTest, EventsAreBitwiseSoNegativeZeroEndsAnEvent) {
  Image plus = Flat(1, 1, 0.0f), minus = Flat(1, 1, -0.0f);
  SequenceAnalysis analysis = Analyze({plus, plus, minus});
  EXPECT_EQ(analysis.eventsByDuration, (std::vector<uint64_t>{0, 1, 1, 0}));
}

TEST(SequenceAnalysisTest, SingleFrameIsOneEventAndNoPrediction) {
  SequenceAnalysis analysis = Analyze({Flat(2, 2, 0.3f)});
  EXPECT_EQ(analysis.eventsByDuration, (std::vector<uint64_t>{0, 4}));
  EXPECT_EQ(analysis.frameToFrame.count, 0u);
  EXPECT_TRUE(analysis.longTermByFrame.empty());
  EXPECT_DOUBLE_EQ(analysis.d, 0.0);
  EXPECT_TRUE(analysis.predictions.empty());
  nlohmann::json json = analysis.ToJson();
  EXPECT_TRUE(json["frame_to_frame"]["mean"].is_null());
}

TEST(SequenceAnalysisTest, PredictionsFollowEquation3UpToTheSequenceOrTheCap) {
  std::vector<Image> frames(5, Flat(2, 2, 0.0f));
  SetPixel(&frames[3], 1, 1, 1.0f);
  SequenceAnalysis analysis = Analyze(frames);
  ASSERT_EQ(analysis.predictions.size(), 4u);  // bin widths 2..5
  for (const auto& p : analysis.predictions) {
    EXPECT_DOUBLE_EQ(p.relativeCost, Equation3RelativeCost(5, p.binWidth, analysis.d));
    EXPECT_DOUBLE_EQ(p.performanceRatio * p.relativeCost, 1.0);
  }
  EXPECT_EQ(analysis.predictions.front().binWidth, 2);
  SequenceAnalysis longer = Analyze(std::vector<Image>(100, Flat(1, 1, 0.0f)));
  ASSERT_EQ(longer.predictions.size(), size_t(kMaxPredictedBinWidth - 1));
  EXPECT_EQ(longer.predictions.back().binWidth, kMaxPredictedBinWidth);
}

TEST(SequenceAnalysisTest, JsonHasSnakeCaseFieldsAndNoMask) {
  std::vector<Image> frames(3, Flat(2, 1, 0.0f));
  SetPixel(&frames[2], 0, 0, 1.0f);
  nlohmann::json json = Analyze(frames).ToJson();
  EXPECT_EQ(json["frames"], 3);
  EXPECT_EQ(json["width"], 2);
  EXPECT_EQ(json["events_by_duration"], (std::vector<uint64_t>{0, 1, 1, 1}));
  EXPECT_DOUBLE_EQ(json["frame_to_frame"]["mean"].get<double>(), 0.75);
  EXPECT_EQ(json["long_term"]["by_frame"], (std::vector<double>{1.0, 0.5}));
  EXPECT_DOUBLE_EQ(json["changed_pixel_share"].get<double>(), 0.5);
  EXPECT_EQ(json["predictions"][0]["bin_width"], 2);
  EXPECT_TRUE(json.contains("volume_share_by_duration"));
  EXPECT_TRUE(json.contains("event_duration_std_dev"));
  EXPECT_FALSE(json.contains("change_mask"));
}

TEST(SequenceAnalysisTest, RejectsBadFrames) {
  SequenceAnalyzer analyzer;
  EXPECT_THROW(analyzer.Finish(), std::logic_error);
  EXPECT_THROW(analyzer.Add(Image{}), std::invalid_argument);
  Image malformed = Flat(2, 2, 0.0f);
  malformed.rgb.pop_back();
  EXPECT_THROW(analyzer.Add(malformed), std::invalid_argument);
  analyzer.Add(Flat(2, 2, 0.0f));
  try {
    analyzer.Add(Flat(3, 2, 0.0f));
    FAIL() << "a frame of another size was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("3x2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2x2"), std::string::npos) << e.what();
  }
  EXPECT_EQ(analyzer.FrameCount(), 1);
}

// The same analysis with every frame in memory, event by event, pixel by pixel.
SequenceAnalysis NaiveAnalysis(const std::vector<Image>& frames) {
  SequenceAnalysis analysis;
  const int count = static_cast<int>(frames.size());
  const size_t pixels = frames[0].PixelCount();
  analysis.frames = count;
  analysis.eventsByDuration.assign(count + 1, 0);
  analysis.changeMask.assign(pixels, 0);
  auto same = [&](int f, int g, size_t p) {
    return std::memcmp(&frames[f].rgb[3 * p], &frames[g].rgb[3 * p], 3 * sizeof(float)) == 0;
  };
  for (size_t p = 0; p < pixels; ++p) {
    int start = 0;
    for (int f = 1; f <= count; ++f) {
      if (f < count && same(f - 1, f, p)) continue;
      ++analysis.eventsByDuration[f - start];
      if (f < count) analysis.changeMask[p] = 1;
      start = f;
    }
  }
  for (int f = 1; f < count; ++f) {
    analysis.frameToFrameByFrame.push_back(Coherence(frames[f - 1], frames[f]));
    analysis.longTermByFrame.push_back(Coherence(frames[0], frames[f]));
  }
  return analysis;
}

TEST(SequenceAnalysisTest, IncrementalEqualsNaiveOnARandomSequence) {
  std::mt19937 random(42);
  std::uniform_int_distribution<int> level(0, 2);   // few levels: pixels often stay put
  std::uniform_real_distribution<double> chance(0, 1);
  std::vector<Image> frames{Flat(9, 7, 0.0f)};
  for (float& v : frames[0].rgb) v = float(level(random));
  for (int f = 1; f < 23; ++f) {
    Image next = frames.back();
    for (size_t p = 0; p < next.PixelCount(); ++p) {
      if (chance(random) < 0.3) next.rgb[3 * p + level(random)] = float(level(random));
    }
    frames.push_back(next);
  }
  SequenceAnalysis incremental = Analyze(frames), naive = NaiveAnalysis(frames);
  EXPECT_EQ(incremental.eventsByDuration, naive.eventsByDuration);
  EXPECT_EQ(incremental.changeMask, naive.changeMask);
  EXPECT_EQ(incremental.frameToFrameByFrame, naive.frameToFrameByFrame);
  EXPECT_EQ(incremental.longTermByFrame, naive.longTermByFrame);
  EXPECT_NEAR(Sum(incremental.volumeShareByDuration), 1.0, 1e-12);
  // The sequence is random enough to exercise more than a couple of durations.
  int durations = 0;
  for (uint64_t count : naive.eventsByDuration) durations += count > 0;
  EXPECT_GE(durations, 5);
}

// A frame traced only where it may change, as the farm's planners do: every changed pixel
// is traced, and so are some that come out with their old bits (ties) or go back to the
// first frame's value. Every fifth frame is traced in full, as a bin's end or a segment's
// start is.
TEST(SequenceAnalysisTest, ChangesGiveWhatWholeFramesGive) {
  std::mt19937 random(7);
  std::uniform_int_distribution<int> level(0, 1);
  std::uniform_real_distribution<double> chance(0, 1);
  SequenceAnalyzer whole, byChanges, byTraced;
  Image frame = Flat(11, 5, 0.0f);
  for (float& v : frame.rgb) v = float(level(random));
  const Image first = frame;
  std::vector<uint8_t> wholeMask, changesMask, tracedMask;
  whole.Add(frame, &wholeMask);
  byChanges.Add(frame, &changesMask);
  byTraced.AddTraced(frame, std::vector<uint8_t>(frame.PixelCount(), 0), &tracedMask);  // the first is whole
  EXPECT_EQ(wholeMask, changesMask);
  EXPECT_EQ(wholeMask, tracedMask);
  size_t ties = 0, backToFirst = 0;
  for (int f = 1; f < 31; ++f) {
    std::vector<uint8_t> traced(frame.PixelCount(), 0);
    for (size_t p = 0; p < frame.PixelCount(); ++p) {
      if (f % 5 != 0 && chance(random) >= 0.4) continue;  // copied: keeps its bits
      traced[p] = 1;
      const float before[3] = {frame.rgb[3 * p], frame.rgb[3 * p + 1], frame.rgb[3 * p + 2]};
      frame.rgb[3 * p + level(random)] = float(level(random));
      ties += std::memcmp(before, &frame.rgb[3 * p], sizeof before) == 0;
      backToFirst += std::memcmp(&first.rgb[3 * p], &frame.rgb[3 * p], sizeof before) == 0;
    }
    whole.Add(frame, &wholeMask);
    byChanges.AddChanges(FrameChanges::Gather(frame, traced), &changesMask);
    byTraced.AddTraced(frame, traced, &tracedMask);
    ASSERT_EQ(wholeMask, changesMask) << "frame " << f;
    ASSERT_EQ(wholeMask, tracedMask) << "frame " << f;
  }
  EXPECT_GT(ties, 20u);
  EXPECT_GT(backToFirst, 20u);
  const SequenceAnalysis expected = whole.Finish();
  for (const SequenceAnalyzer* analyzer : {&byChanges, &byTraced}) {
    const SequenceAnalysis actual = analyzer->Finish();
    EXPECT_EQ(actual.ToJson(), expected.ToJson());
    EXPECT_EQ(actual.changeMask, expected.changeMask);
  }
}

TEST(SequenceAnalysisTest, GatherTakesTheMarkedPixelsInOrder) {
  Image frame = Flat(5, 3, 0.0f);
  for (size_t i = 0; i < frame.rgb.size(); ++i) frame.rgb[i] = float(i);
  std::vector<uint8_t> mask(15, 0);
  mask[0] = mask[9] = mask[14] = 1;  // either side of a skipped word, and the tail
  const FrameChanges changes = FrameChanges::Gather(frame, mask);
  EXPECT_EQ(changes.pixels, (std::vector<uint32_t>{0, 9, 14}));
  EXPECT_EQ(changes.rgb, (std::vector<float>{0, 1, 2, 27, 28, 29, 42, 43, 44}));
  EXPECT_THROW(FrameChanges::Gather(frame, std::vector<uint8_t>(14, 1)), std::invalid_argument);
  SequenceAnalyzer analyzer;
  analyzer.Add(frame);
  EXPECT_THROW(analyzer.AddTraced(frame, std::vector<uint8_t>(16, 1)), std::invalid_argument);
}

TEST(SequenceAnalysisTest, RejectsBadChanges) {
  SequenceAnalyzer analyzer;
  EXPECT_THROW(analyzer.AddChanges(FrameChanges{}), std::invalid_argument);  // no first frame
  analyzer.Add(Flat(2, 2, 0.0f));
  EXPECT_THROW(analyzer.AddChanges(FrameChanges{{2, 1}, std::vector<float>(6, 1.0f)}), std::invalid_argument);
  EXPECT_THROW(analyzer.AddChanges(FrameChanges{{4}, std::vector<float>(3, 1.0f)}), std::invalid_argument);
  EXPECT_THROW(analyzer.AddChanges(FrameChanges{{1}, std::vector<float>(2, 1.0f)}), std::invalid_argument);
  EXPECT_EQ(analyzer.FrameCount(), 1);
  analyzer.AddChanges(FrameChanges{{1}, {1.0f, 1.0f, 1.0f}});
  EXPECT_EQ(analyzer.Finish().frameToFrameByFrame, (std::vector<double>{0.75}));
}

TEST(SequenceAnalysisTest, FinishCanBeCalledMidSequence) {
  SequenceAnalyzer analyzer;
  analyzer.Add(Flat(1, 1, 0.0f));
  analyzer.Add(Flat(1, 1, 0.0f));
  EXPECT_EQ(analyzer.Finish().eventsByDuration, (std::vector<uint64_t>{0, 0, 1}));
  analyzer.Add(Flat(1, 1, 1.0f));
  EXPECT_EQ(analyzer.Finish().eventsByDuration, (std::vector<uint64_t>{0, 1, 1, 0}));
}

// The paper's Figure 9, "Theoretical" column: N = 60 frames, printed to two figures.
TEST(Equation3Test, MatchesThePapersFigure9) {
  const double kPaperRounding = 0.015;
  const double firstAnimation[] = {0.54, 0.38, 0.3, 0.26, 0.22, 0.21, 0.19, 0.18};  // n = 3..10
  for (int n = 3; n <= 10; ++n) {
    EXPECT_NEAR(Equation3RelativeCost(60, n, 0.05), firstAnimation[n - 3], kPaperRounding) << n;
  }
  EXPECT_NEAR(Equation3RelativeCost(60, 10, 0.14), 0.25, kPaperRounding);
  EXPECT_NEAR(Equation3RelativeCost(60, 10, 0.18), 0.29, kPaperRounding);
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(60, 2, 0.05), 1.0);  // n = 2 traces every frame
}

TEST(Equation3Test, ReducesToEquations1And2) {
  // d = 0 and N - 1 a multiple of n - 1 (the paper's convention): P = N / (1 + (N-1)/(n-1)).
  EXPECT_DOUBLE_EQ(1 / Equation3RelativeCost(61, 7, 0.0), 61.0 / (1 + 60.0 / 6));
  // One bin, all frames differing: every frame traced in full.
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(9, 9, 1.0), 1.0);
  // The remainder term: 10 frames with n = 4 are 3 whole bins (9 steps), each costing its
  // far end and half of its 2 inner frames, and no remainder; 11 frames leave one step, a
  // bin of two frames that traces its far end.
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(10, 4, 0.5), (1 + 3 * 2.0) / 10);
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(11, 4, 0.5), (1 + 3 * 2.0 + 1) / 11);
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(1, 5, 0.5), 1.0);
}

TEST(Equation3Test, DependsOnlyOnTheNumberOfBins) {
  for (int frames = 2; frames <= 80; ++frames) {
    for (int n = 2; n <= 70; ++n) {
      int bins = (frames - 1 + n - 2) / (n - 1);  // ceil((N-1)/(n-1))
      EXPECT_NEAR(Equation3RelativeCost(frames, n, 0.13),
                  (1 + bins + (frames - 1 - bins) * 0.13) / frames, 1e-12)
          << frames << " " << n;
    }
  }
}

TEST(Equation3Test, RejectsBadArguments) {
  EXPECT_THROW(Equation3RelativeCost(60, 1, 0.05), std::invalid_argument);
  EXPECT_THROW(Equation3RelativeCost(0, 4, 0.05), std::invalid_argument);
  EXPECT_THROW(BestBinWidth(60, 0.05, 1), std::invalid_argument);
  EXPECT_THROW(BestBinWidth(0, 0.05, 10), std::invalid_argument);
}

TEST(Equation3Test, BestBinWidthIsTheArgmin) {
  EXPECT_EQ(BestBinWidth(60, 0.05, 10), 10);
  EXPECT_EQ(BestBinWidth(60, 0.05, 2), 2);
  // With every pixel changing each frame all bin widths cost the same: the smallest wins.
  EXPECT_EQ(BestBinWidth(60, 1.0, 10), 2);
  // Bin widths with as many bins cost the same: N = 60 needs 4 bins for any n in 16..20.
  EXPECT_EQ(BestBinWidth(60, 0.05, 20), 16);
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(60, 16, 0.05), Equation3RelativeCost(60, 20, 0.05));
  EXPECT_DOUBLE_EQ(Equation3RelativeCost(60, 16, 0.05), (1 + 4 + (59 - 4) * 0.05) / 60);
  for (int cap = 2; cap <= 64; ++cap) {
    int best = BestBinWidth(60, 0.18, cap);
    for (int n = 2; n <= cap; ++n) {
      EXPECT_LE(Equation3RelativeCost(60, best, 0.18),
                Equation3RelativeCost(60, n, 0.18) * (1 + 1e-12));
    }
  }
}

}  // namespace
}  // namespace tcfarm
