// What a job's speed cost in error, measured while it renders.
//
// Spot checks (always on): a random sample of each finished frame's copied pixels is
// traced again, by the coordinator's referee, and compared bitwise; the mismatch rate,
// scaled by the copied share, is an estimate of the job's share of wrong pixels, with a
// Wilson 95 % interval. The sample costs at most kMaxSpotCheckShare extra rays. (Traced
// pixels need no such check here: the referee's unseen sample, farm/referee_sample.h,
// traces a share of every value a worker sends.)
//
// Verification (on request): selected frames are also rendered in full, brute force,
// and compared with the job's frames: pixels differing, max abs error, PSNR, SSIM. A
// frame's reference is traced only after the job's frame is finished, so memory holds
// just the frames being verified.
#pragma once

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/dispute.h"
#include "proto/frame/compare.h"
#include "proto/frame/frame_io.h"
#include "proto/pixel_set/pixel_set.h"

namespace tcfarm {

struct VerificationOptions {
  // Frames (relative to the job) to render in full for comparison; empty: none.
  std::vector<int> referenceFrames;
  // Share of each frame's copied pixels traced again; 0 turns spot checks off.
  double spotCheckShare = 0.01;
  uint64_t seed = 1;
  // The strategy promises 0 wrong pixels (exact, brute): then any disagreement a check
  // finds is a bug or a worker that returns wrong values, and the job is marked suspect.
  bool promisesExact = false;
};

// The share of a frame's pixels spot checks may trace again (the promise of <= 2 %).
constexpr double kMaxSpotCheckShare = 0.02;

// Frames to verify for a request: "all", or an evenly spread sample of `count` frames.
std::vector<int> FramesToVerify(int frameCount, bool all, int count);

class Verification {
 public:
  struct Request {
    uint64_t id;
    int frame;  // relative to the job
    PixelSet pixels;
  };

  Verification(int width, int height, int frameCount, VerificationOptions options);

  // A frame of the job is finished: schedule its spot checks and, when asked, its
  // reference.
  void OnFrameFinished(int frame, const std::vector<float>& rgb, const std::vector<uint8_t>& traced);
  // A frame kept from before a restart: only its reference, when one is asked for.
  void OnKeptFrame(int frame, const std::vector<float>& rgb);
  // The frame now shows `rgb` (a repair rewrote it): a reference asked for it compares
  // with these values, traced again where it was compared already.
  void Reverify(int frame, const std::vector<float>& rgb);
  bool WantsReference(int frame) const { return wantsReference_[static_cast<size_t>(frame)]; }
  // A worker found to return wrong values: the references it traced say nothing. Returns
  // their frames, which the caller reverifies (Reverify) with the values they show.
  std::vector<int> ForgetReferencesBy(const std::string& checker);
  std::vector<Request> TakeRequests();
  // Returns false for an id this verification did not issue (or already answered).
  // checker: the worker that traced it, named in the dispute a disagreement raises.
  bool OnResult(uint64_t id, const float* rgb, size_t floatCount, const std::string& checker = "");
  // The referee's unseen sample found `pixels` of `frame` sent wrong: for a job that
  // promises exactness, the frame is suspect like one a check disagreed on.
  void OnWrongValues(int frame, uint64_t pixels);
  // A spot check that cannot be traced (the referee could not build the scene): given up,
  // and counted as such in the report. Unknown ids are ignored.
  void Abandon(uint64_t id, const std::string& why);
  // Disagreements found since the last call, for a job that promises exactness.
  std::vector<Dispute> TakeDisputes();
  // Whether an outstanding request traces part of a reference frame (not a spot check).
  bool IsReference(uint64_t id) const { return outstanding_.count(id) > 0 && spotChecks_.count(id) == 0; }
  bool Pending() const { return !outstanding_.empty() || !ready_.empty(); }
  // A job that promises exactness and whose checks found a disagreement.
  bool Suspect() const { return options_.promisesExact && !suspectFrames_.empty(); }
  uint64_t ExtraPixels() const { return extraPixels_; }

  nlohmann::json Report() const;

 private:
  struct SpotCheck {
    int frame;
    std::vector<uint32_t> pixels;
    std::vector<float> values;  // the job's values, in pixels' order
  };
  // Samples `share` of the frame's copied pixels.
  void ScheduleSpotCheck(int frame, const std::vector<float>& rgb, const std::vector<uint8_t>& traced,
                         double share);
  // Tallies a check's answer by who traced it.
  void CountChecker(const std::string& checker, uint64_t pixels);
  void ScheduleReference(int frame, const std::vector<float>& rgb);
  uint64_t Issue(int frame, PixelSet pixels);
  // A check of `frame` found `pixels` that disagree with the job's values; `dispute`
  // holds a sample of them.
  void NoteDisagreement(int frame, uint64_t pixels, Dispute dispute);

  int width_, height_, frameCount_;
  VerificationOptions options_;
  std::mt19937_64 random_;
  uint64_t nextId_ = 1;
  std::vector<Request> ready_;
  std::map<uint64_t, int> outstanding_;  // id -> frame
  std::map<uint64_t, SpotCheck> spotChecks_;
  std::map<uint64_t, Image> jobFramesAwaitingReference_;
  std::vector<bool> wantsReference_;
  // Each compared frame's reference, and who traced it: a reference by a worker found
  // wrong is forgotten and traced again (ForgetReferencesBy), and so is one of a frame
  // rewritten since (Reverify).
  struct ReferenceResult {
    FrameError error;
    double ssim = 1;
    std::string checker;
  };
  std::map<int, ReferenceResult> references_;
  // Figures
  uint64_t extraPixels_ = 0;
  uint64_t checkedPixels_ = 0, mismatchedPixels_ = 0;
  uint64_t abandonedPixels_ = 0;  // of spot checks given up (Abandon)
  std::string abandonedWhy_;       // the first reason
  uint64_t copiedPixels_ = 0, totalPixels_ = 0;
  uint64_t checkedByReferee_ = 0, checkedByWorkers_ = 0;  // pixels, every kind of check
  std::map<int, uint64_t> suspectFrames_;  // frame -> pixels a check disagreed on
  std::vector<Dispute> disputes_;
};

}  // namespace tcfarm
