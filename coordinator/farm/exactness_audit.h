// What a job that promises exactness does when its own checks disagree with it.
//
// 1. The disagreement becomes a dispute (farm/dispute.h), which the coordinator's
//    referee settles by tracing the disputed pixels itself (farm/referee.h).
// 2. Whoever sent bits that are not the truth is distrusted: the checker, and the worker
//    that traced a wrong value the job shows where the frame's own task traced it (the
//    ledger). A copy is never evidence against anyone: the frame is repaired, and the
//    referee's unseen sample (farm/referee_sample.h) judges the workers. The farm then
//    drops them and gives them no more tasks.
// 3. Every frame a distrusted worker's values can have reached (TracerLedger) is traced
//    again in full by another worker and rewritten where it differs. A job keeps its
//    promise even when a worker lied, as long as one honest worker remains.
//
// The job is marked suspect all the same (Verification reports it): a disagreement
// means a bug or a bad worker, and a person should look. Owned by the job's run; not
// thread-safe.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/dispute.h"
#include "coordinator/farm/referee.h"
#include "coordinator/farm/tracer_ledger.h"

namespace tcfarm {

class ExactnessAudit {
 public:
  // referee: null leaves disputes unsettled (reported as such), as in unit tests of the
  // parts around it. firstFrame: the job's first frame in the scene's numbering. Every
  // job disputes wrong traces (Verification's trace checks), so every job keeps which
  // pixels each worker traced, for as long as a dispute can need them (ForgetBefore).
  // keptFrames: by frame (the job's), those kept from before a restart: their values were
  // sent to an earlier run, so a dispute there names nobody (its frame is repaired).
  ExactnessAudit(uint64_t jobId, int firstFrame, int frameCount, Referee* referee,
                 std::vector<bool> keptFrames = {});

  // The job's values: which worker traced which pixels; reach: the frames after `frame`
  // into which the job may copy them.
  void OnTraced(int frame, const std::string& worker, const PixelSet& pixels, int reach) {
    ledger_.Record(frame, worker, pixels, reach);
  }
  // Workers whose values frame may show, traced there or copied: its checks avoid them.
  std::set<std::string> WorkersReaching(int frame) const { return ledger_.WorkersReaching(frame); }
  // No check below `frame` is outstanding any more (the job's numbering): what only a
  // dispute there could need is forgotten, as far as open disputes allow.
  void ForgetBefore(int frame);
  uint64_t PixelSetsHeld() const { return ledger_.PixelSetsHeld(); }

  struct SceneRef {
    std::string hash;
    std::string json;
  };
  // Sends disputes to the referee; scene() is called once, the first time one is sent.
  void Open(std::vector<Dispute> disputes, const std::function<SceneRef()>& scene);

  using Verdict = tcfarm::Verdict;
  // The referee's answers so far: the workers they show returned wrong values, each
  // named once per job.
  std::vector<Verdict> HearReferee();

  // A worker found wrong, by this job or another: the frames its values reached are owed
  // a repair. `name`: how the job record names it.
  void OnWorkerDistrusted(const std::string& worker, const std::string& name);
  // Frames owed a repair whose files are written (`written` says), now in repair.
  std::vector<int> TakeFramesToRepair(const std::function<bool(int frame)>& written);
  // A repair of `frame` by `worker` came back; `changed` of its pixels differed from
  // what was written (and are now rewritten).
  void OnRepaired(int frame, const std::string& worker, const PixelSet& pixels, uint64_t changed);

  // Disputes at the referee or repairs owed: the job is not done.
  bool Pending() const { return !openDisputes_.empty() || !owedRepairs_.empty() || !repairing_.empty(); }
  const std::set<std::string>& Distrusted() const { return distrusted_; }
  // What was settled and repaired; null while nothing was disputed.
  nlohmann::json Report() const;

 private:
  void Distrust(const std::string& worker, const std::string& why, std::vector<Verdict>& verdicts);
  // A dispute at the referee, with who sent each disputed pixel's value in the job as the
  // dispute was raised: a repair may rewrite the frame before the referee answers, and the
  // values disputed are still the ones sent before it.
  struct OpenDispute {
    Dispute dispute;
    std::map<uint32_t, std::string> senders;  // by pixel; none for a copy or where unknown
  };
  void Rule(const OpenDispute& open, const Referee::Answer& answer, std::vector<Verdict>& verdicts);

  uint64_t jobId_;
  int firstFrame_, frameCount_;
  Referee* referee_;
  std::vector<bool> keptFrames_;
  TracerLedger ledger_;
  std::optional<SceneRef> scene_;  // asked for with the first dispute
  uint64_t nextDispute_ = 1;
  std::map<uint64_t, OpenDispute> openDisputes_;
  std::set<std::string> distrusted_;     // found wrong by this job's disputes, or told
  std::vector<std::string> distrustedNames_;
  std::set<int> owedRepairs_, repairing_, repaired_;
  // Figures for the report
  int disputesSettled_ = 0;
  int checksWrong_ = 0;  // disputes where the checker's values were not the truth
  int jobWrong_ = 0;     // disputes where the job's values were not the truth
  std::vector<std::string> unsettled_;  // why the referee could not answer
  int framesRewritten_ = 0;
  uint64_t pixelsRewritten_ = 0;
};

}  // namespace tcfarm
