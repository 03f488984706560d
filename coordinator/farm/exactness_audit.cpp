#include "coordinator/farm/exactness_audit.h"

#include <algorithm>
#include <cstdio>

namespace tcfarm {

ExactnessAudit::ExactnessAudit(uint64_t jobId, int firstFrame, int frameCount, Referee* referee)
    : jobId_(jobId), firstFrame_(firstFrame), frameCount_(frameCount), referee_(referee) {}

void ExactnessAudit::Open(std::vector<Dispute> disputes, const std::function<SceneRef()>& scene) {
  for (Dispute& dispute : disputes) {
    if (!referee_) {
      unsettled_.push_back("frame " + std::to_string(firstFrame_ + dispute.frame) + ": no referee to settle it");
      continue;
    }
    if (!scene_) scene_ = scene();
    const uint64_t id = nextDispute_++;
    referee_->Ask({jobId_, id, scene_->hash, scene_->json, firstFrame_ + dispute.frame, dispute.pixels});
    openDisputes_[id] = std::move(dispute);
  }
}

std::vector<ExactnessAudit::Verdict> ExactnessAudit::HearReferee() {
  std::vector<Verdict> verdicts;
  if (!referee_ || openDisputes_.empty()) return verdicts;
  for (Referee::Answer& answer : referee_->TakeAnswers(jobId_)) {
    auto dispute = openDisputes_.find(answer.id);
    if (dispute == openDisputes_.end()) continue;
    Rule(dispute->second, answer, verdicts);
    openDisputes_.erase(dispute);
  }
  return verdicts;
}

void ExactnessAudit::Rule(const Dispute& dispute, const Referee::Answer& answer, std::vector<Verdict>& verdicts) {
  const int frame = firstFrame_ + dispute.frame;
  if (!answer.error.empty()) {
    unsettled_.push_back("frame " + std::to_string(frame) + ": the referee could not trace it: " + answer.error);
    return;
  }
  const Ruling ruling = Settle(dispute, answer.rgb);
  ++disputesSettled_;
  if (ruling.checkerWrong) {
    ++checksWrong_;
    Distrust(dispute.checker, "its check of frame " + std::to_string(frame) + " returned values the referee did not",
             verdicts);
  }
  if (ruling.jobWrong.empty()) return;
  ++jobWrong_;
  // The frame shows wrong values, whoever sent them: it is repaired, and whoever may have
  // sent them is watched more closely from now on.
  owedRepairs_.insert(dispute.frame);
  for (const std::string& worker : ledger_.WorkersReaching(dispute.frame)) suspects_.insert(worker);
}

std::set<std::string> ExactnessAudit::TakeSuspects() {
  std::set<std::string> suspects;
  suspects.swap(suspects_);
  return suspects;
}

void ExactnessAudit::Distrust(const std::string& worker, const std::string& why, std::vector<Verdict>& verdicts) {
  // The referee is the truth: its values are never the ones found wrong.
  if (worker.empty() || worker == Referee::kName || distrusted_.count(worker)) return;
  for (const Verdict& verdict : verdicts) {
    if (verdict.worker == worker) return;
  }
  verdicts.push_back({worker, why});
}

void ExactnessAudit::OnWorkerDistrusted(const std::string& worker, const std::string& name) {
  if (!distrusted_.insert(worker).second) return;
  distrustedNames_.push_back(name);
  for (int frame : ledger_.FramesReachedBy(worker, frameCount_)) owedRepairs_.insert(frame);
}

std::vector<int> ExactnessAudit::TakeFramesToRepair(const std::function<bool(int frame)>& written) {
  std::vector<int> frames;
  for (auto it = owedRepairs_.begin(); it != owedRepairs_.end();) {
    // A frame in repair already is repaired again once that repair is back.
    if (written(*it) && !repairing_.count(*it)) {
      frames.push_back(*it);
      repairing_.insert(*it);
      it = owedRepairs_.erase(it);
    } else {
      ++it;
    }
  }
  return frames;
}

void ExactnessAudit::OnRepaired(int frame, const std::string& worker, uint64_t changed) {
  repairing_.erase(frame);
  repaired_.insert(frame);
  // The frame now shows the repairer's values: if it is found wrong in turn, this frame
  // is repaired again.
  ledger_.Record(frame, worker, 0);
  if (distrusted_.count(worker)) owedRepairs_.insert(frame);
  if (changed == 0) return;
  ++framesRewritten_;
  pixelsRewritten_ += changed;
}

nlohmann::json ExactnessAudit::Report() const {
  if (disputesSettled_ == 0 && unsettled_.empty() && openDisputes_.empty() && distrusted_.empty()) return nullptr;
  return {{"disputes_settled", disputesSettled_},
          {"disputes_open", openDisputes_.size()},
          {"checks_wrong", checksWrong_},
          {"job_values_wrong", jobWrong_},
          {"unsettled", unsettled_},
          {"workers_distrusted", distrustedNames_},
          {"frames_retraced", repaired_.size()},
          {"frames_rewritten", framesRewritten_},
          {"pixels_rewritten", pixelsRewritten_},
          {"repairs_owed", owedRepairs_.size() + repairing_.size()}};
}

}  // namespace tcfarm
