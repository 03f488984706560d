#include "coordinator/farm/verification.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "coordinator/farm/referee.h"
#include "proto/frame/ssim.h"

namespace tcfarm {
namespace {

// Wilson score interval at 95 % for k successes in n trials.
std::pair<double, double> WilsonInterval(uint64_t k, uint64_t n) {
  if (n == 0) return {0, 1};
  constexpr double z = 1.959963984540054;
  double p = double(k) / n, z2n = z * z / n;
  double centre = (p + z2n / 2) / (1 + z2n);
  double half = z * std::sqrt(p * (1 - p) / n + z2n / (4.0 * n)) / (1 + z2n);
  return {std::max(0.0, centre - half), std::min(1.0, centre + half)};
}

}  // namespace

std::vector<int> FramesToVerify(int frameCount, bool all, int count) {
  std::vector<int> frames;
  if (all) count = frameCount;
  count = std::clamp(count, 0, frameCount);
  for (int i = 0; i < count; ++i) {
    // Evenly spread, first and last included when count > 1.
    int frame = count == 1 ? frameCount / 2
                           : static_cast<int>(std::lround(double(i) * (frameCount - 1) / (count - 1)));
    if (frames.empty() || frames.back() != frame) frames.push_back(frame);
  }
  return frames;
}

Verification::Verification(int width, int height, int frameCount, VerificationOptions options)
    : width_(width),
      height_(height),
      frameCount_(frameCount),
      options_(std::move(options)),
      random_(options_.seed),
      wantsReference_(static_cast<size_t>(frameCount), false) {
  options_.spotCheckShare = std::clamp(options_.spotCheckShare, 0.0, kMaxSpotCheckShare);
  for (int frame : options_.referenceFrames) {
    if (frame < 0 || frame >= frameCount) {
      throw std::invalid_argument("verification frame " + std::to_string(frame) +
                                  " is outside the job's 0.." + std::to_string(frameCount - 1));
    }
    wantsReference_[frame] = true;
  }
}

uint64_t Verification::Issue(int frame, PixelSet pixels) {
  uint64_t id = nextId_++;
  extraPixels_ += pixels.size();
  outstanding_[id] = frame;
  ready_.push_back({id, frame, std::move(pixels)});
  return id;
}

void Verification::OnFrameFinished(int frame, const std::vector<float>& rgb, const std::vector<uint8_t>& traced) {
  size_t pixels = traced.size();
  size_t copied = pixels - std::count(traced.begin(), traced.end(), uint8_t{1});
  copiedPixels_ += copied;
  totalPixels_ += pixels;
  if (wantsReference_[frame]) {
    ScheduleReference(frame, rgb);  // checks every pixel: no sample needed
    return;
  }
  if (copied > 0 && options_.spotCheckShare > 0) ScheduleSpotCheck(frame, rgb, traced, options_.spotCheckShare);
}

void Verification::OnKeptFrame(int frame, const std::vector<float>& rgb) {
  if (wantsReference_[frame]) ScheduleReference(frame, rgb);
}

void Verification::Reverify(int frame, const std::vector<float>& rgb) {
  if (!wantsReference_[static_cast<size_t>(frame)]) return;
  for (auto& [id, image] : jobFramesAwaitingReference_) {
    // Its reference is being traced: it will be compared with what the frame shows now.
    if (outstanding_.count(id) && outstanding_.at(id) == frame) {
      image.rgb = rgb;
      return;
    }
  }
  references_.erase(frame);
  ScheduleReference(frame, rgb);
}

std::vector<int> Verification::ForgetReferencesBy(const std::string& checker) {
  std::vector<int> frames;
  for (auto it = references_.begin(); it != references_.end();) {
    if (it->second.checker != checker) {
      ++it;
      continue;
    }
    frames.push_back(it->first);
    it = references_.erase(it);
  }
  return frames;
}

void Verification::ScheduleSpotCheck(int frame, const std::vector<float>& rgb, const std::vector<uint8_t>& traced,
                                     double share) {
  size_t pixels = traced.size();
  auto wanted = static_cast<size_t>(std::ceil(share * pixels));
  // Sample uniformly: draw indices, keep the copied ones, bounded attempts.
  std::vector<uint32_t> chosen;
  std::uniform_int_distribution<uint32_t> pick(0, static_cast<uint32_t>(pixels - 1));
  for (size_t attempt = 0; attempt < 8 * wanted && chosen.size() < wanted; ++attempt) {
    uint32_t p = pick(random_);
    if (traced[p] == 0) chosen.push_back(p);
  }
  if (chosen.empty()) return;
  std::sort(chosen.begin(), chosen.end());
  chosen.erase(std::unique(chosen.begin(), chosen.end()), chosen.end());
  SpotCheck check{frame, chosen, {}};
  for (uint32_t p : chosen) check.values.insert(check.values.end(), &rgb[3 * p], &rgb[3 * p + 3]);
  uint64_t id = Issue(frame, PixelSet::FromSortedIndices(chosen));
  spotChecks_[id] = std::move(check);
}

void Verification::ScheduleReference(int frame, const std::vector<float>& rgb) {
  uint64_t id = Issue(frame, PixelSet::Full(static_cast<uint32_t>(width_) * height_));
  jobFramesAwaitingReference_[id] = Image{width_, height_, rgb};
}

std::vector<Verification::Request> Verification::TakeRequests() {
  std::vector<Request> requests;
  requests.swap(ready_);
  return requests;
}

namespace {

// The pixels (of `count`, 3 floats each in `job` and `check`) whose values differ, and
// a dispute over an evenly spread sample of at most kMaxDisputedPixels of them.
// `indexOf` maps a position to its pixel index.
template <typename IndexOf>
std::pair<uint64_t, Dispute> Disagreements(int frame, size_t count, const float* job, const float* check,
                                           IndexOf indexOf, const std::string& checker) {
  std::vector<size_t> differing;
  for (size_t i = 0; i < count; ++i) {
    if (!SameBits(&job[3 * i], &check[3 * i])) differing.push_back(i);
  }
  Dispute dispute{frame, checker, {}, {}, {}};
  const size_t step = std::max<size_t>(1, (differing.size() + kMaxDisputedPixels - 1) / kMaxDisputedPixels);
  for (size_t k = 0; k < differing.size(); k += step) {
    const size_t i = differing[k];
    dispute.pixels.push_back(indexOf(i));
    dispute.jobValues.insert(dispute.jobValues.end(), &job[3 * i], &job[3 * i + 3]);
    dispute.checkerValues.insert(dispute.checkerValues.end(), &check[3 * i], &check[3 * i + 3]);
  }
  return {differing.size(), std::move(dispute)};
}

}  // namespace

bool Verification::OnResult(uint64_t id, const float* rgb, size_t floatCount, const std::string& checker) {
  auto outstanding = outstanding_.find(id);
  if (outstanding == outstanding_.end()) return false;
  const int frame = outstanding->second;
  outstanding_.erase(outstanding);
  if (auto check = spotChecks_.find(id); check != spotChecks_.end()) {
    const SpotCheck& spot = check->second;
    if (floatCount != spot.values.size()) throw std::invalid_argument("spot check size");
    auto [mismatched, dispute] = Disagreements(
        spot.frame, floatCount / 3, spot.values.data(), rgb, [&](size_t i) { return spot.pixels[i]; }, checker);
    CountChecker(checker, floatCount / 3);
    checkedPixels_ += floatCount / 3;
    mismatchedPixels_ += mismatched;
    if (mismatched > 0) NoteDisagreement(spot.frame, mismatched, std::move(dispute));
    spotChecks_.erase(check);
    return true;
  }
  auto job = jobFramesAwaitingReference_.find(id);
  if (job == jobFramesAwaitingReference_.end()) return false;
  Image reference{width_, height_, std::vector<float>(rgb, rgb + floatCount)};
  CountChecker(checker, floatCount / 3);
  const FrameError frameError = CompareImages(reference, job->second);
  if (frameError.differingPixels > 0) {
    auto [differing, dispute] = Disagreements(
        frame, floatCount / 3, job->second.rgb.data(), rgb, [](size_t i) { return static_cast<uint32_t>(i); },
        checker);
    NoteDisagreement(frame, differing, std::move(dispute));
  }
  references_[frame] = {frameError, Ssim(reference, job->second), checker};
  jobFramesAwaitingReference_.erase(job);
  return true;
}

void Verification::CountChecker(const std::string& checker, uint64_t pixels) {
  (checker == Referee::kName ? checkedByReferee_ : checkedByWorkers_) += pixels;
}

void Verification::NoteDisagreement(int frame, uint64_t pixels, Dispute dispute) {
  const bool first = suspectFrames_.empty();
  suspectFrames_[frame] += pixels;
  if (!options_.promisesExact) return;  // the strategy's approximation, measured
  disputes_.push_back(std::move(dispute));
  if (!first) return;
  std::fprintf(stderr, "coordinator: a check found %llu pixels of frame %d that disagree with the job's, which "
               "promises none: a bug or a worker returning wrong values; the job is marked suspect and the "
               "coordinator traces the disputed pixels itself to settle who is wrong\n",
               static_cast<unsigned long long>(pixels), frame);
}

void Verification::Abandon(uint64_t id, const std::string& why) {
  auto check = spotChecks_.find(id);
  if (check == spotChecks_.end()) return;
  abandonedPixels_ += check->second.pixels.size();
  if (abandonedWhy_.empty()) abandonedWhy_ = why;
  spotChecks_.erase(check);
  outstanding_.erase(id);
}

void Verification::OnWrongValues(int frame, uint64_t pixels) {
  if (pixels > 0) suspectFrames_[frame] += pixels;
}

std::vector<Dispute> Verification::TakeDisputes() {
  std::vector<Dispute> disputes;
  disputes.swap(disputes_);
  return disputes;
}

nlohmann::json Verification::Report() const {
  nlohmann::json report;
  double copiedShare = totalPixels_ ? double(copiedPixels_) / totalPixels_ : 0;
  auto [low, high] = WilsonInterval(mismatchedPixels_, checkedPixels_);
  report["spot_checks"] = {
      {"pixels_checked", checkedPixels_},
      {"mismatches", mismatchedPixels_},
      // Share of all pixels estimated wrong: copied share x mismatch rate among copies.
      {"estimated_error_percent",
       checkedPixels_ ? 100 * copiedShare * mismatchedPixels_ / double(checkedPixels_) : 0.0},
      {"ci95_percent", {100 * copiedShare * low, 100 * copiedShare * high}}};
  if (abandonedPixels_ > 0) {
    report["spot_checks"]["pixels_abandoned"] = abandonedPixels_;
    report["spot_checks"]["abandoned_why"] = abandonedWhy_;
  }
  if (!options_.referenceFrames.empty()) {
    FrameError compared;
    double ssimSum = 0;
    for (const auto& [frame, result] : references_) {
      compared += result.error;
      ssimSum += result.ssim;
    }
    const int framesCompared = static_cast<int>(references_.size());
    const double psnr = compared.Psnr();
    report["reference"] = {
        {"frames_requested", options_.referenceFrames.size()},
        {"frames_compared", framesCompared},
        {"pixels_differing", compared.differingPixels},
        {"percent_differing", 100 * compared.DifferingShare()},
        {"max_abs_error", compared.maxAbsError},
        {"psnr_db", std::isinf(psnr) ? nlohmann::json(nullptr) : nlohmann::json(psnr)},
        {"ssim", framesCompared ? ssimSum / framesCompared : 1.0}};
  }
  // Who traced the checks, references included: never the worker whose values they check.
  report["checked_by"] = {{"referee_pixels", checkedByReferee_}, {"worker_pixels", checkedByWorkers_}};
  report["extra_pixels_traced"] = extraPixels_;
  if (Suspect()) {
    nlohmann::json frames = nlohmann::json::object();
    uint64_t pixels = 0;
    for (const auto& [frame, count] : suspectFrames_) {
      frames[std::to_string(frame)] = count;
      pixels += count;
    }
    report["suspect"] = {{"pixels_disagreeing", pixels},
                         {"frames", frames},
                         {"why", "the strategy promises 0 wrong pixels, yet pixels traced again disagree with "
                                 "what the job was sent: a bug or a worker returning wrong values"}};
  }
  return report;
}

}  // namespace tcfarm
