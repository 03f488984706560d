#include "coordinator/farm/tracer_ledger.h"

#include <algorithm>

namespace tcfarm {

void TracerLedger::Record(int frame, const std::string& worker, int window) {
  int& longest = frames_[frame][worker];
  longest = std::max(longest, window);
}

std::set<std::string> TracerLedger::WorkersOf(int frame) const {
  std::set<std::string> workers;
  auto found = frames_.find(frame);
  if (found == frames_.end()) return workers;
  for (const auto& [worker, window] : found->second) workers.insert(worker);
  return workers;
}

std::set<std::string> TracerLedger::WorkersReaching(int frame) const {
  std::set<std::string> workers;
  for (auto it = frames_.upper_bound(frame); it != frames_.begin();) {
    --it;
    for (const auto& [worker, window] : it->second) {
      if (it->first + window >= frame) workers.insert(worker);
    }
  }
  return workers;
}

std::set<int> TracerLedger::FramesReachedBy(const std::string& worker, int frameCount) const {
  std::set<int> reached;
  for (const auto& [frame, workers] : frames_) {
    auto traced = workers.find(worker);
    if (traced == workers.end()) continue;
    // A horizon is at most frame + window + 1, "valid through the window": copies reach
    // frame + window at the furthest.
    for (int f = frame; f <= frame + traced->second && f < frameCount; ++f) reached.insert(f);
  }
  return reached;
}

}  // namespace tcfarm
