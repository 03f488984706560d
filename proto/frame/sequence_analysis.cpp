#include "proto/frame/sequence_analysis.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "proto/frame/compare.h"

namespace tcfarm {
namespace {

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

nlohmann::json StatsJson(const RunningStats& stats, const std::vector<double>& byFrame) {
  if (stats.count == 0) {
    return {{"mean", nullptr}, {"min", nullptr}, {"max", nullptr}, {"by_frame", byFrame}};
  }
  return {{"mean", stats.Mean()}, {"min", stats.min}, {"max", stats.max}, {"by_frame", byFrame}};
}

void SummarizeEvents(SequenceAnalysis* analysis) {
  const double volume = double(analysis->frames) * analysis->width * analysis->height;
  const auto& events = analysis->eventsByDuration;
  analysis->volumeShareByDuration.assign(events.size(), 0.0);
  uint64_t count = 0;
  for (size_t duration = 1; duration < events.size(); ++duration) {
    analysis->volumeShareByDuration[duration] = double(duration) * events[duration] / volume;
    count += events[duration];
  }
  analysis->eventCount = count;
  // Every pixel of every frame lies in exactly one event, so the durations sum to the volume.
  analysis->meanEventDuration = volume / double(count);
  double squares = 0;
  for (size_t duration = 1; duration < events.size(); ++duration) {
    double deviation = double(duration) - analysis->meanEventDuration;
    squares += deviation * deviation * double(events[duration]);
  }
  analysis->eventDurationStdDev = std::sqrt(squares / double(count));
}

void Predict(SequenceAnalysis* analysis) {
  int widest = std::min(analysis->frames, kMaxPredictedBinWidth);
  for (int n = 2; n <= widest; ++n) {
    double cost = Equation3RelativeCost(analysis->frames, n, analysis->d);
    analysis->predictions.push_back({n, cost, 1.0 / cost});
  }
}

}  // namespace

double SequenceAnalysis::ChangedPixelShare() const {
  if (changeMask.empty()) return 0;
  size_t changed = std::count(changeMask.begin(), changeMask.end(), uint8_t{1});
  return double(changed) / double(changeMask.size());
}

nlohmann::json SequenceAnalysis::ToJson() const {
  nlohmann::json predictionsJson = nlohmann::json::array();
  for (const auto& p : predictions) {
    predictionsJson.push_back({{"bin_width", p.binWidth},
                               {"relative_cost", p.relativeCost},
                               {"performance_ratio", p.performanceRatio}});
  }
  return {{"frames", frames},
          {"width", width},
          {"height", height},
          {"frame_to_frame", StatsJson(frameToFrame, frameToFrameByFrame)},
          {"long_term", StatsJson(longTerm, longTermByFrame)},
          {"events_by_duration", eventsByDuration},
          {"volume_share_by_duration", volumeShareByDuration},
          {"event_count", eventCount},
          {"mean_event_duration", meanEventDuration},
          {"event_duration_std_dev", eventDurationStdDev},
          {"d", d},
          {"predictions", predictionsJson},
          {"changed_pixel_share", ChangedPixelShare()}};
}

void SequenceAnalyzer::CheckShape(const Image& frame) const {
  if (frame.width <= 0 || frame.height <= 0 || frame.rgb.size() != frame.PixelCount() * 3) {
    throw std::invalid_argument("frame of " + SizeText(frame.width, frame.height) + " holds " +
                                std::to_string(frame.rgb.size()) + " floats; expected " +
                                std::to_string(frame.PixelCount() * 3));
  }
  if (frames_ > 0 && (frame.width != width_ || frame.height != height_)) {
    throw std::invalid_argument("frame of " + SizeText(frame.width, frame.height) +
                                " in a sequence of " + SizeText(width_, height_));
  }
}

void SequenceAnalyzer::Start(const Image& frame) {
  width_ = frame.width;
  height_ = frame.height;
  first_ = previous_ = frame;
  runLength_.assign(frame.PixelCount(), 1);
  changed_.assign(frame.PixelCount(), 0);
  closedEventsByDuration_.assign(2, 0);
}

SequenceAnalyzer::Equal SequenceAnalyzer::AdvanceRuns(const Image& frame, std::vector<uint8_t>* unchanged) {
  // One pass over the frame: it is compared with the previous frame and the first, and
  // the previous frame becomes this one pixel by pixel, only where it changed.
  Equal equal;
  uint8_t* mask = unchanged ? unchanged->data() : nullptr;
  float* previous = previous_.rgb.data();
  const float* current = frame.rgb.data();
  const float* first = first_.rgb.data();
  for (size_t pixel = 0; pixel < runLength_.size(); ++pixel) {
    const size_t at = 3 * pixel;
    equal.toFirst += SameBits(first + at, current + at);
    const bool same = SameBits(previous + at, current + at);
    if (mask) mask[pixel] = same;
    if (same) {
      ++runLength_[pixel];
      ++equal.toPrevious;
      continue;
    }
    std::memcpy(previous + at, current + at, 3 * sizeof(float));
    ++closedEventsByDuration_[runLength_[pixel]];
    runLength_[pixel] = 1;
    changed_[pixel] = 1;
  }
  return equal;
}

void SequenceAnalyzer::Add(const Image& frame, std::vector<uint8_t>* unchanged) {
  CheckShape(frame);
  if (frames_ == 0) {
    if (unchanged) unchanged->assign(frame.PixelCount(), 1);
    Start(frame);
    frames_ = 1;
    return;
  }
  if (unchanged) unchanged->resize(frame.PixelCount());  // AdvanceRuns sets every pixel
  ++frames_;
  // A run can now last up to frames_ frames: index frames_ must exist.
  closedEventsByDuration_.resize(frames_ + 1, 0);
  const Equal equal = AdvanceRuns(frame, unchanged);
  const double pixels = double(runLength_.size());
  const double frameToFrame = double(equal.toPrevious) / pixels, longTerm = double(equal.toFirst) / pixels;
  frameToFrame_.Add(frameToFrame);
  longTerm_.Add(longTerm);
  frameToFrameByFrame_.push_back(frameToFrame);
  longTermByFrame_.push_back(longTerm);
}

std::vector<uint64_t> SequenceAnalyzer::EventsIncludingOpenRuns() const {
  // Every pixel's current run ends with the last frame seen: count it as a finished event.
  std::vector<uint64_t> events = closedEventsByDuration_;
  events.resize(frames_ + 1, 0);
  for (uint32_t run : runLength_) ++events[run];
  return events;
}

SequenceAnalysis SequenceAnalyzer::Finish() const {
  if (frames_ == 0) throw std::logic_error("sequence analysis of no frames");
  SequenceAnalysis analysis;
  analysis.frames = frames_;
  analysis.width = width_;
  analysis.height = height_;
  analysis.frameToFrame = frameToFrame_;
  analysis.longTerm = longTerm_;
  analysis.frameToFrameByFrame = frameToFrameByFrame_;
  analysis.longTermByFrame = longTermByFrame_;
  analysis.eventsByDuration = EventsIncludingOpenRuns();
  SummarizeEvents(&analysis);
  analysis.d = frameToFrame_.count ? 1.0 - frameToFrame_.Mean() : 0.0;
  Predict(&analysis);
  analysis.changeMask = changed_;
  return analysis;
}

double Equation3RelativeCost(int frames, int binWidth, double d) {
  if (binWidth < 2) {
    throw std::invalid_argument("bin width " + std::to_string(binWidth) + "; expected >= 2");
  }
  if (frames < 1) {
    throw std::invalid_argument("sequence of " + std::to_string(frames) +
                                " frames; expected >= 1");
  }
  const int steps = frames - 1, stepsPerBin = binWidth - 1;
  const int wholeBins = steps / stepsPerBin, remainder = steps % stepsPerBin;
  double a = 1 + wholeBins * (1 + (binWidth - 2) * d);
  double b = remainder == 0 ? 0 : (remainder - 1) * d + 1;
  return (a + b) / frames;
}

int BestBinWidth(int frames, double d, int maxBinWidth) {
  if (maxBinWidth < 2) {
    throw std::invalid_argument("largest bin width " + std::to_string(maxBinWidth) +
                                "; expected >= 2");
  }
  // Widths that give the same number of bins cost the same in exact arithmetic; the
  // tolerance keeps rounding from choosing the wider one.
  const double kTieTolerance = 1e-12;
  int best = 2;
  double bestCost = Equation3RelativeCost(frames, 2, d);
  for (int n = 3; n <= maxBinWidth; ++n) {
    double cost = Equation3RelativeCost(frames, n, d);
    if (cost < bestCost * (1 - kTieTolerance)) {
      best = n;
      bestCost = cost;
    }
  }
  return best;
}

}  // namespace tcfarm
