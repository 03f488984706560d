// The referee's unseen sample: the one check of a job that no worker can see, and so the
// one that still holds when any number of workers with valid keys collude.
//
// Every result a worker sends a job (the planner's tasks, checks and repairs alike) gives
// up a secret random share of its pixels once it is back: the values the worker sent for
// them are kept, and the coordinator's referee (farm/referee.h) traces those pixels of
// that frame itself. A value that differs is evidence against the worker that sent it,
// and against nobody else: it sent that value for that pixel of that frame, and two honest
// traces of one pixel give the same bits. Copies a strategy made are never sampled.
//
// A horizon is a value sent too. A worker that answers an `exact` task with horizon h for
// a pixel says the pixel keeps the value it sent through frame h - 1, and exact copies it
// there on that word alone. So a drawn pixel whose horizon reaches past its frame is also
// traced by the referee at the last frame the horizon vouches for (within the job): a
// different value there is evidence against the worker just as a wrong trace is. An honest
// worker's horizons are conservative (exact is bit-identical to brute force), so no honest
// worker fails this.
//
// Nothing a worker sees depends on the sample. It is drawn after the result is back, by a
// generator seeded per job from the operating system's random source, and traced on the
// coordinator: a worker cannot tell a watched task from another, so it cannot behave well
// only while watched, and no number of colluding workers can vouch for each other.
//
// Sizing: each pixel a worker sends is drawn with probability s, independently. A worker
// that alters k of the pixels it sends in each of F frames goes unseen with probability
// (1 - s)^(kF). A job's s is the least that catches k = 16 over the job's frames with
// probability 1 - 1e-6, within [kMinShare, kMaxShare]; the report states the probability
// the job actually gets, and what it cost (pixels and the referee's CPU seconds).
//
// Owned by the job's run; not thread-safe.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/dispute.h"
#include "coordinator/farm/referee.h"
#include "proto/pixel_set/pixel_set.h"

namespace tcfarm {

class RefereeSample {
 public:
  // The least share the sample takes, whatever the job's length: a long job catches a
  // worker altering one pixel a frame all the same (1 - 0.99^F).
  static constexpr double kMinShare = 0.01;
  // The most: a one-frame job pays a tenth of its pixels and states its lower probability.
  static constexpr double kMaxShare = 0.10;
  // How much more of a worker's values on probation (its first tasks) are drawn.
  static constexpr double kProbationFactor = 4;
  // The pixels altered a frame the sizing aims to catch, and how surely, per job.
  static constexpr int kSizedForAlteredPixels = 16;
  static constexpr double kSizedForMissProbability = 1e-6;
  // Sampled values the referee may owe a job before the job waits for it to catch up:
  // bounds the coordinator's memory when the referee falls behind the workers.
  static constexpr uint64_t kMaxOutstandingPixels = uint64_t{1} << 20;

  // The share a job of `frames` frames samples.
  static double ShareFor(int frames);
  // The probability that a worker altering `alteredPerFrame` of the pixels it sends in
  // each of `frames` frames is caught by a sample of `share`.
  static double CatchProbability(double share, int alteredPerFrame, int frames);

  // referee: null turns the sample off (unit tests of the parts around it). seed: 0 draws
  // it from the operating system's random source, as the farm does; tests pass their own.
  RefereeSample(uint64_t jobId, int firstFrame, int frameCount, Referee* referee, uint64_t seed = 0);

  double share() const { return share_; }
  // `worker` sent `rgb` (3 floats a pixel, in pixels' order) for `pixels` of `frame` (the
  // job's numbering), and with them, for an exact task, `horizons` (one a pixel, the
  // scene's numbering, as on the wire). The referee's own values and distrusted workers'
  // are not sampled.
  // onProbation: the worker joined lately; its values are drawn kProbationFactor times as
  // often, and it cannot tell (nothing it sees changes).
  void OnValues(int frame, const std::string& worker, const PixelSet& pixels, const float* rgb,
                const int32_t* horizons = nullptr, bool onProbation = false);
  // A frame kept from before a coordinator restart: what was drawn of its values then went
  // with the run that drew it, so a share of what it shows is drawn now. Nobody is known
  // to have sent those values (the ledger went with that run too): a wrong one names no
  // worker, and its frame is owed a repair (TakeKeptFramesWrong). Only for strategies that
  // promise exactness: other strategies' copies differ from the referee by design.
  void OnKeptValues(int frame, const std::vector<float>& rgb);
  // Kept frames whose drawn values the referee found wrong, since the last call.
  std::set<int> TakeKeptFramesWrong();
  // A frame a check found wrong may show the worker's values: from now on its values are
  // drawn as a worker's on probation are. Nothing it sees changes.
  void Suspect(const std::string& worker) { suspects_.insert(worker); }
  // A worker found wrong: its values are retraced in full by others, so no more of them
  // are sampled.
  void OnWorkerDistrusted(const std::string& worker) { distrusted_.insert(worker); }

  // Sends what was drawn since the last call to the referee, one question a frame.
  // sceneJson() is called once, the first time a question is sent.
  void Ask(const std::string& sceneHash, const std::function<const std::string&()>& sceneJson);
  // The referee's answers so far: each worker whose values differ from its own, once.
  std::vector<Verdict> HearReferee();

  // Drawn pixels the referee's answers since the last call found wrong, by frame (the
  // job's): the job was sent wrong values there, and a person should look.
  std::map<int, uint64_t> TakeWrongPixels();

  // Drawn values not yet answered: the job is not done while any remain.
  bool Pending() const { return outstandingPixels_ > 0; }
  // The referee owes this job so much that its workers should wait for it.
  bool Behind() const { return outstandingPixels_ >= kMaxOutstandingPixels; }
  nlohmann::json Report() const;

 private:
  // 20 bytes a drawn value: at kMaxOutstandingPixels, 20 MiB.
  struct Drawn {
    uint32_t pixel;
    uint32_t worker;  // in workers_
    float rgb[3];
    int sentFor;  // the frame the value was sent for: earlier than the question's for a horizon
  };
  uint32_t WorkerIndex(const std::string& worker);
  // Draws pixels, skipping ahead geometrically between draws; each drawn pixel is asked
  // at its frame and, where its horizon vouches for later frames, at the last of them.
  // Draws pixels with `gap` between draws, `untilNext` to the next.
  void Draw(int frame, uint32_t worker, const PixelSet& pixels, const float* rgb, const int32_t* horizons,
            std::geometric_distribution<uint64_t>& gap, uint64_t& untilNext);
  void Add(int askedAt, Drawn drawn);
  void Rule(const std::vector<Drawn>& drawn, int frame, const Referee::Answer& answer,
            std::vector<Verdict>& verdicts);

  uint64_t jobId_;
  int firstFrame_, frameCount_;
  Referee* referee_;
  double share_, probationShare_;
  std::mt19937_64 random_;
  // Pixels passed over before the next draw, and how many are left to pass: one sequence
  // for workers on probation, one for the others.
  std::geometric_distribution<uint64_t> gap_, probationGap_;
  uint64_t untilNextDraw_, untilNextProbationDraw_;
  std::map<int, std::vector<Drawn>> toAsk_;           // by frame (the job's)
  std::map<uint64_t, std::pair<int, std::vector<Drawn>>> asked_;  // by question id
  uint64_t nextQuestion_ = 1;
  uint64_t outstandingPixels_ = 0;
  std::vector<std::string> workers_;  // principals, as Drawn names them
  std::set<std::string> distrusted_;
  std::set<std::string> suspects_;
  std::set<std::string> caught_;  // by this sample
  std::map<int, uint64_t> wrongByFrame_;  // since the last TakeWrongPixels
  std::set<int> keptFramesWrong_;         // since the last TakeKeptFramesWrong
  // In workers_, the name of values kept from before a restart: no principal is spelled so.
  static constexpr const char* kKeptFromBefore = "kept from before a restart";
  static constexpr uint32_t kNoWorker = UINT32_MAX;
  uint32_t keptMark_ = kNoWorker;
  uint64_t keptPixelsDrawn_ = 0;
  int keptFramesRepaired_ = 0;
  std::vector<std::string> unsettled_;
  // Figures
  uint64_t pixelsSent_ = 0, pixelsDrawn_ = 0, horizonChecks_ = 0, tracesAnswered_ = 0, pixelsWrong_ = 0;
  double refereeCpuSeconds_ = 0;
};

}  // namespace tcfarm
