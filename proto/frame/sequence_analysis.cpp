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

// Calls visit(pixel) for each pixel whose byte in mask is non-zero, in order. Most of a
// traced mask is zero where little changes, and all ones where a frame is traced in full:
// both are passed over a word at a time.
template <typename Visit>
void ForEachMarked(const std::vector<uint8_t>& mask, Visit visit) {
  constexpr uint64_t kAllOnes = 0x0101010101010101;
  const uint8_t* bytes = mask.data();
  const size_t count = mask.size();
  size_t pixel = 0;
  for (uint64_t word = 0; pixel + sizeof word <= count; pixel += sizeof word) {
    std::memcpy(&word, bytes + pixel, sizeof word);
    if (word == 0) continue;
    if (word == kAllOnes) {
      for (size_t i = pixel; i < pixel + sizeof word; ++i) visit(i);
      continue;
    }
    for (size_t i = pixel; i < pixel + sizeof word; ++i) {
      if (bytes[i] != 0) visit(i);
    }
  }
  for (; pixel < count; ++pixel) {
    if (bytes[pixel] != 0) visit(pixel);
  }
}

void Predict(SequenceAnalysis* analysis) {
  int widest = std::min(analysis->frames, kMaxPredictedBinWidth);
  for (int n = 2; n <= widest; ++n) {
    double cost = Equation3RelativeCost(analysis->frames, n, analysis->d);
    analysis->predictions.push_back({n, cost, 1.0 / cost});
  }
}

void CheckMask(const Image& frame, const std::vector<uint8_t>& mayChange) {
  if (mayChange.size() != frame.PixelCount() || frame.rgb.size() != frame.PixelCount() * 3) {
    throw std::invalid_argument("a mask of " + std::to_string(mayChange.size()) + " pixels for a frame of " +
                                SizeText(frame.width, frame.height));
  }
}

}  // namespace

FrameChanges FrameChanges::Gather(const Image& frame, const std::vector<uint8_t>& mayChange) {
  CheckMask(frame, mayChange);
  size_t marked = 0;
  ForEachMarked(mayChange, [&](size_t) { ++marked; });
  FrameChanges changes;
  changes.pixels.reserve(marked);
  changes.rgb.reserve(3 * marked);
  const float* rgb = frame.rgb.data();
  ForEachMarked(mayChange, [&](size_t pixel) {
    changes.pixels.push_back(static_cast<uint32_t>(pixel));
    for (size_t c = 3 * pixel; c < 3 * pixel + 3; ++c) changes.rgb.push_back(rgb[c]);
  });
  return changes;
}

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

void SequenceAnalyzer::CheckChanges(const FrameChanges& changes) const {
  if (frames_ == 0) throw std::invalid_argument("a sequence's first frame must be given whole, not by its changes");
  if (changes.rgb.size() != changes.pixels.size() * 3) {
    throw std::invalid_argument("frame changes of " + std::to_string(changes.pixels.size()) + " pixels hold " +
                                std::to_string(changes.rgb.size()) + " floats; expected 3 per pixel");
  }
  const size_t pixels = eventStart_.size();
  for (size_t i = 0; i < changes.pixels.size(); ++i) {
    if (changes.pixels[i] >= pixels || (i > 0 && changes.pixels[i] <= changes.pixels[i - 1])) {
      throw std::invalid_argument("frame changes list pixel " + std::to_string(changes.pixels[i]) + " at " +
                                  std::to_string(i) + "; expected ascending pixels below " + std::to_string(pixels));
    }
  }
}

void SequenceAnalyzer::Start(const Image& frame) {
  width_ = frame.width;
  height_ = frame.height;
  first_ = previous_ = frame;
  eventStart_.assign(frame.PixelCount(), 0);
  sameAsFirst_.assign(frame.PixelCount(), 1);
  sameAsFirstCount_ = frame.PixelCount();
  closedEventsByDuration_.assign(2, 0);
}

void SequenceAnalyzer::BeginFrame(std::vector<uint8_t>* unchanged) {
  if (unchanged) unchanged->assign(eventStart_.size(), 1);
  ++frames_;
  // A run can now last up to frames_ frames: index frames_ must exist.
  closedEventsByDuration_.resize(frames_ + 1, 0);
}

bool SequenceAnalyzer::AdvancePixel(size_t pixel, const float* value, uint8_t* mask) {
  const size_t at = 3 * pixel;
  float* previous = previous_.rgb.data() + at;
  if (SameBits(previous, value)) return false;
  // The pixel's event ran from its start up to the frame before this one.
  const uint32_t frame = static_cast<uint32_t>(frames_ - 1);
  ++closedEventsByDuration_[frame - eventStart_[pixel]];
  eventStart_[pixel] = frame;
  std::memcpy(previous, value, 3 * sizeof(float));
  const uint8_t sameAsFirst = SameBits(first_.rgb.data() + at, value);
  sameAsFirstCount_ = sameAsFirstCount_ - sameAsFirst_[pixel] + sameAsFirst;
  sameAsFirst_[pixel] = sameAsFirst;
  if (mask) mask[pixel] = 0;
  return true;
}

void SequenceAnalyzer::EndFrame(size_t changedPixels) {
  const double pixels = double(eventStart_.size());
  const double frameToFrame = double(eventStart_.size() - changedPixels) / pixels;
  const double longTerm = double(sameAsFirstCount_) / pixels;
  frameToFrame_.Add(frameToFrame);
  longTerm_.Add(longTerm);
  frameToFrameByFrame_.push_back(frameToFrame);
  longTermByFrame_.push_back(longTerm);
}

void SequenceAnalyzer::Add(const Image& frame, std::vector<uint8_t>* unchanged) {
  CheckShape(frame);
  if (frames_ == 0) {
    if (unchanged) unchanged->assign(frame.PixelCount(), 1);
    Start(frame);
    frames_ = 1;
    return;
  }
  BeginFrame(unchanged);
  uint8_t* mask = unchanged ? unchanged->data() : nullptr;
  const float* values = frame.rgb.data();
  size_t changed = 0;
  for (size_t pixel = 0; pixel < eventStart_.size(); ++pixel) changed += AdvancePixel(pixel, values + 3 * pixel, mask);
  EndFrame(changed);
}

void SequenceAnalyzer::AddTraced(const Image& frame, const std::vector<uint8_t>& mayChange,
                                 std::vector<uint8_t>* unchanged) {
  CheckShape(frame);
  CheckMask(frame, mayChange);
  if (frames_ == 0) return Add(frame, unchanged);
  BeginFrame(unchanged);
  uint8_t* mask = unchanged ? unchanged->data() : nullptr;
  const float* values = frame.rgb.data();
  size_t changed = 0;
  ForEachMarked(mayChange, [&](size_t pixel) { changed += AdvancePixel(pixel, values + 3 * pixel, mask); });
  EndFrame(changed);
}

void SequenceAnalyzer::AddChanges(const FrameChanges& changes, std::vector<uint8_t>* unchanged) {
  CheckChanges(changes);
  BeginFrame(unchanged);
  uint8_t* mask = unchanged ? unchanged->data() : nullptr;
  size_t changed = 0;
  for (size_t i = 0; i < changes.pixels.size(); ++i) {
    changed += AdvancePixel(changes.pixels[i], changes.rgb.data() + 3 * i, mask);
  }
  EndFrame(changed);
}

std::vector<uint64_t> SequenceAnalyzer::EventsIncludingOpenRuns() const {
  // Every pixel's current run ends with the last frame seen: count it as a finished event.
  std::vector<uint64_t> events = closedEventsByDuration_;
  events.resize(frames_ + 1, 0);
  for (uint32_t start : eventStart_) ++events[static_cast<uint32_t>(frames_) - start];
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
  // A pixel has changed once its current event began after the first frame.
  analysis.changeMask.resize(eventStart_.size());
  std::transform(eventStart_.begin(), eventStart_.end(), analysis.changeMask.begin(),
                 [](uint32_t start) { return uint8_t{start != 0}; });
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
