#include "coordinator/farm/referee_sample.h"

#include <algorithm>
#include <cmath>

#include "proto/frame/compare.h"

namespace tcfarm {
namespace {

uint64_t SecretSeed() {
  std::random_device source;  // the operating system's random source
  return (uint64_t{source()} << 32) ^ source();
}

}  // namespace

double RefereeSample::ShareFor(int frames) {
  // (1 - s)^(kF) <= miss  <=>  s >= 1 - miss^(1 / kF)
  const double draws = double(kSizedForAlteredPixels) * std::max(1, frames);
  const double share = 1 - std::pow(kSizedForMissProbability, 1 / draws);
  return std::clamp(share, kMinShare, kMaxShare);
}

double RefereeSample::CatchProbability(double share, int alteredPerFrame, int frames) {
  // log1p keeps the tiny miss probabilities of long jobs from rounding to 1 - 1.
  const double logMiss = std::log1p(-share) * double(alteredPerFrame) * std::max(0, frames);
  return -std::expm1(logMiss);
}

RefereeSample::RefereeSample(uint64_t jobId, int firstFrame, int frameCount, Referee* referee, uint64_t seed)
    : jobId_(jobId),
      firstFrame_(firstFrame),
      frameCount_(frameCount),
      referee_(referee),
      share_(ShareFor(frameCount)),
      probationShare_(std::min(kProbationFactor * share_, 0.5)),
      random_(seed != 0 ? seed : SecretSeed()),
      gap_(share_),
      probationGap_(probationShare_),
      untilNextDraw_(gap_(random_)),
      untilNextProbationDraw_(probationGap_(random_)) {}

void RefereeSample::OnValues(int frame, const std::string& worker, const PixelSet& pixels, const float* rgb,
                             const int32_t* horizons, bool onProbation) {
  if (!referee_ || worker == Referee::kName || distrusted_.count(worker)) return;
  pixelsSent_ += pixels.size();
  const uint32_t index = WorkerIndex(worker);
  if (onProbation || suspects_.count(worker)) {
    Draw(frame, index, pixels, rgb, horizons, probationGap_, untilNextProbationDraw_);
  } else {
    Draw(frame, index, pixels, rgb, horizons, gap_, untilNextDraw_);
  }
}

void RefereeSample::OnKeptValues(int frame, const std::vector<float>& rgb) {
  if (!referee_) return;
  if (keptMark_ == kNoWorker) keptMark_ = WorkerIndex(kKeptFromBefore);
  const uint64_t before = pixelsDrawn_;
  Draw(frame, keptMark_, PixelSet::Full(static_cast<uint32_t>(rgb.size() / 3)), rgb.data(), nullptr, gap_,
       untilNextDraw_);
  keptPixelsDrawn_ += pixelsDrawn_ - before;
}

std::set<int> RefereeSample::TakeKeptFramesWrong() {
  std::set<int> frames;
  frames.swap(keptFramesWrong_);
  return frames;
}

uint32_t RefereeSample::WorkerIndex(const std::string& worker) {
  // A job has few workers: a linear search beats a map here.
  const auto found = std::find(workers_.begin(), workers_.end(), worker);
  if (found != workers_.end()) return static_cast<uint32_t>(found - workers_.begin());
  workers_.push_back(worker);
  return static_cast<uint32_t>(workers_.size() - 1);
}

void RefereeSample::Draw(int frame, uint32_t worker, const PixelSet& pixels, const float* rgb,
                         const int32_t* horizons, std::geometric_distribution<uint64_t>& gap, uint64_t& untilNext) {
  uint64_t position = 0;  // of the span's first pixel in rgb
  for (const Span& span : pixels.spans()) {
    const uint64_t length = span.size();
    uint64_t at = 0;
    while (untilNext < length - at) {
      at += untilNext;
      const uint64_t i = position + at;
      const Drawn drawn{static_cast<uint32_t>(span.begin + at), worker, {rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]},
                        frame};
      Add(frame, drawn);
      if (horizons) {
        // The last frame the horizon vouches for, within the job (the job's numbering).
        const int vouchedThrough = std::min(int64_t{horizons[i]} - firstFrame_ - 1, int64_t{frameCount_} - 1);
        if (vouchedThrough > frame) {
          Add(vouchedThrough, drawn);
          ++horizonChecks_;
        }
      }
      ++pixelsDrawn_;
      ++at;
      untilNext = gap(random_);
    }
    untilNext -= length - at;
    position += length;
  }
}

void RefereeSample::Add(int askedAt, Drawn drawn) {
  toAsk_[askedAt].push_back(std::move(drawn));
  ++outstandingPixels_;
}

void RefereeSample::Ask(const std::string& sceneHash, const std::function<const std::string&()>& sceneJson) {
  if (!referee_ || toAsk_.empty()) return;
  const std::string& json = sceneJson();
  for (auto& [frame, drawn] : toAsk_) {
    std::vector<uint32_t> pixels;
    pixels.reserve(drawn.size());
    for (const Drawn& d : drawn) pixels.push_back(d.pixel);
    const uint64_t id = nextQuestion_++;
    referee_->Ask({jobId_, id, sceneHash, json, firstFrame_ + frame, std::move(pixels), Referee::Purpose::kSample});
    asked_[id] = {frame, std::move(drawn)};
  }
  toAsk_.clear();
}

std::vector<Verdict> RefereeSample::HearReferee() {
  std::vector<Verdict> verdicts;
  if (!referee_ || asked_.empty()) return verdicts;
  for (const Referee::Answer& answer : referee_->TakeAnswers(jobId_, Referee::Purpose::kSample)) {
    auto asked = asked_.find(answer.id);
    if (asked == asked_.end()) continue;
    const auto& [frame, drawn] = asked->second;
    Rule(drawn, frame, answer, verdicts);
    outstandingPixels_ -= drawn.size();
    asked_.erase(asked);
  }
  return verdicts;
}

void RefereeSample::Rule(const std::vector<Drawn>& drawn, int frame, const Referee::Answer& answer,
                         std::vector<Verdict>& verdicts) {
  const int absolute = firstFrame_ + frame;
  if (!answer.error.empty() || answer.rgb.size() != 3 * drawn.size()) {
    unsettled_.push_back("frame " + std::to_string(absolute) + ": the referee could not trace its sample: " +
                         (answer.error.empty() ? "an answer of the wrong size" : answer.error));
    return;
  }
  refereeCpuSeconds_ += answer.cpuSeconds;
  tracesAnswered_ += drawn.size();
  for (size_t i = 0; i < drawn.size(); ++i) {
    if (SameBits(drawn[i].rgb, &answer.rgb[3 * i])) continue;
    ++pixelsWrong_;
    ++wrongByFrame_[frame];
    const Drawn& wrong = drawn[i];
    if (wrong.worker == keptMark_) {
      if (keptFramesWrong_.insert(frame).second) ++keptFramesRepaired_;
      continue;  // sent to the run before the restart: evidence against nobody here
    }
    const std::string& worker = workers_[wrong.worker];
    if (!caught_.insert(worker).second) continue;
    const std::string pixel = "pixel " + std::to_string(wrong.pixel);
    verdicts.push_back(
        {worker, wrong.sentFor == frame
                           ? pixel + " of frame " + std::to_string(absolute) +
                                 " as it sent it is not the referee's value (the referee's unseen sample)"
                           : pixel + " as it sent it for frame " + std::to_string(firstFrame_ + wrong.sentFor) +
                                 ", with a horizon vouching for it through frame " + std::to_string(absolute) +
                                 ", is not the referee's value there (the referee's unseen sample)"});
  }
}

std::map<int, uint64_t> RefereeSample::TakeWrongPixels() {
  std::map<int, uint64_t> wrong;
  wrong.swap(wrongByFrame_);
  return wrong;
}

nlohmann::json RefereeSample::Report() const {
  const int frames = frameCount_;
  return {{"share", share_},
          {"share_on_probation", probationShare_},
          {"pixels_sent", pixelsSent_},
          {"pixels_sampled", pixelsDrawn_},
          {"horizon_checks", horizonChecks_},  // drawn pixels also traced where their horizon vouches
          {"referee_traces", tracesAnswered_},
          {"pixels_wrong", pixelsWrong_},
          {"workers_caught", caught_.size()},
          {"unsettled", unsettled_},
          {"referee_cpu_seconds", refereeCpuSeconds_},
          // Frames kept from before a restart: what was drawn of them, and how many were
          // found wrong (and repaired).
          {"kept_pixels_sampled", keptPixelsDrawn_},
          {"kept_frames_wrong", keptFramesRepaired_},
          // What the share buys: the chance a worker altering that many of the pixels it
          // sends, in every frame of the job (or in one frame), is caught.
          {"catch_probability",
           {{"altering_16_pixels_every_frame", CatchProbability(share_, 16, frames)},
            {"altering_1_pixel_every_frame", CatchProbability(share_, 1, frames)},
            {"altering_16_pixels_of_one_frame", CatchProbability(share_, 16, 1)}}}};
}

}  // namespace tcfarm
