// What a job that promises exactness does when its own checks disagree with it.
//
// 1. The disagreement becomes a dispute (farm/dispute.h), which the coordinator's
//    referee settles by tracing the disputed pixels itself (farm/referee.h).
// 2. A checker that sent bits that are not the truth is distrusted: they are values it
//    sent for those pixels of that frame. The job's side names nobody: its values may be
//    copies (an approximation, or a horizon gone wrong), may have been traced before a
//    restart, or rewritten by a repair since they were captured. The frame is repaired,
//    and the workers whose values it may show are suspects: the referee's unseen sample
//    (farm/referee_sample.h) draws more of their values, and its evidence judges them.
//    The farm drops a distrusted worker and gives it no more tasks.
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
  // parts around it. firstFrame: the job's first frame in the scene's numbering.
  ExactnessAudit(uint64_t jobId, int firstFrame, int frameCount, Referee* referee);

  // The job's values: `worker` traced part of `frame`; reach: the frames after it into
  // which the job may copy them.
  void OnTraced(int frame, const std::string& worker, int reach) { ledger_.Record(frame, worker, reach); }
  // Workers whose values frame may show, traced there or copied: its checks avoid them.
  std::set<std::string> WorkersReaching(int frame) const { return ledger_.WorkersReaching(frame); }

  struct SceneRef {
    std::string hash;
    std::string json;
  };
  // Sends disputes to the referee; scene() is called once, the first time one is sent.
  void Open(std::vector<Dispute> disputes, const std::function<SceneRef()>& scene);

  using Verdict = tcfarm::Verdict;
  // The referee's answers so far: the checkers they show sent wrong values, each named
  // once per job.
  std::vector<Verdict> HearReferee();
  // Workers whose values a frame the referee found wrong may show, since the last call.
  std::set<std::string> TakeSuspects();

  // A worker found wrong, by this job or another: the frames its values reached are owed
  // a repair. `name`: how the job record names it.
  void OnWorkerDistrusted(const std::string& worker, const std::string& name);
  // The frame shows a wrong value that no worker of this run is known to have sent (a
  // frame kept from before a restart): owed a repair all the same.
  void OweRepair(int frame) { owedRepairs_.insert(frame); }
  // Frames owed a repair whose files are written (`written` says), now in repair.
  std::vector<int> TakeFramesToRepair(const std::function<bool(int frame)>& written);
  // A repair of `frame` by `worker` came back; `changed` of its pixels differed from
  // what was written (and are now rewritten).
  void OnRepaired(int frame, const std::string& worker, uint64_t changed);

  // Disputes at the referee or repairs owed: the job is not done.
  bool Pending() const { return !openDisputes_.empty() || !owedRepairs_.empty() || !repairing_.empty(); }
  const std::set<std::string>& Distrusted() const { return distrusted_; }
  // What was settled and repaired; null while nothing was disputed.
  nlohmann::json Report() const;

 private:
  void Distrust(const std::string& worker, const std::string& why, std::vector<Verdict>& verdicts);
  void Rule(const Dispute& dispute, const Referee::Answer& answer, std::vector<Verdict>& verdicts);

  uint64_t jobId_;
  int firstFrame_, frameCount_;
  Referee* referee_;
  TracerLedger ledger_;
  std::optional<SceneRef> scene_;  // asked for with the first dispute
  uint64_t nextDispute_ = 1;
  std::map<uint64_t, Dispute> openDisputes_;  // at the referee, by question id
  std::set<std::string> suspects_;             // since the last TakeSuspects
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
