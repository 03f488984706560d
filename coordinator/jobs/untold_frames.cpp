#include "coordinator/jobs/untold_frames.h"

#include <algorithm>

namespace tcfarm::jobs {

const std::vector<int>& UntoldFrames::Of(uint64_t job) const {
  static const std::vector<int> kNone;
  const auto owed = untold_.find(job);
  return owed == untold_.end() ? kNone : owed->second.frames;
}

void UntoldFrames::Add(uint64_t job, int frame, int64_t nowMs) {
  Owed& owed = untold_[job];
  if (owed.frames.empty()) owed.sinceMs = nowMs;
  owed.frames.push_back(frame);
}

std::vector<uint64_t> UntoldFrames::DueAt(int64_t nowMs, int64_t intervalMs) const {
  std::vector<uint64_t> due;
  for (const auto& [job, owed] : untold_) {
    if (nowMs - owed.sinceMs >= intervalMs) due.push_back(job);
  }
  return due;
}

void UntoldFrames::Forget(uint64_t job, const std::vector<int>& frames) {
  const auto untold = untold_.find(job);
  if (untold == untold_.end()) return;
  std::vector<int>& owed = untold->second.frames;
  for (int frame : frames) owed.erase(std::remove(owed.begin(), owed.end(), frame), owed.end());
  if (owed.empty()) untold_.erase(untold);
}

}  // namespace tcfarm::jobs
