#include "coordinator/farm/tracer_ledger.h"

#include <algorithm>

namespace tcfarm {

void TracerLedger::Record(int frame, const std::string& worker, const PixelSet& pixels, int window) {
  Traced& traced = frames_[frame][worker];
  traced.window = std::max(traced.window, window);
  if (pixels.empty()) return;
  traced.tasks.push_back(pixels);
  ++pixelSetsHeld_;
}

std::set<std::string> TracerLedger::WorkersOf(int frame) const {
  std::set<std::string> workers;
  auto found = frames_.find(frame);
  if (found == frames_.end()) return workers;
  for (const auto& [worker, traced] : found->second) workers.insert(worker);
  return workers;
}

std::set<std::string> TracerLedger::WorkersReaching(int frame) const {
  std::set<std::string> workers;
  for (auto it = frames_.upper_bound(frame); it != frames_.begin();) {
    --it;
    for (const auto& [worker, traced] : it->second) {
      if (it->first + traced.window >= frame) workers.insert(worker);
    }
  }
  return workers;
}

std::optional<std::string> TracerLedger::TracerAt(int frame, uint32_t pixel) const {
  auto found = frames_.find(frame);
  if (found == frames_.end()) return std::nullopt;
  std::optional<std::string> tracer;
  for (const auto& [worker, traced] : found->second) {
    const bool covered =
        std::any_of(traced.tasks.begin(), traced.tasks.end(), [&](const PixelSet& task) { return task.Contains(pixel); });
    if (!covered) continue;
    if (tracer) return std::nullopt;  // two workers' values: which one the frame shows is not known
    tracer = worker;
  }
  return tracer;
}

void TracerLedger::ForgetPixelsBefore(int frame) {
  int lowestKept = frame;  // frames whose copies still reach `frame` are looked at next time
  for (auto it = frames_.lower_bound(pixelsForgottenBelow_); it != frames_.end() && it->first < frame; ++it) {
    for (auto& [worker, traced] : it->second) {
      if (traced.tasks.empty()) continue;
      if (it->first + traced.window >= frame) {
        lowestKept = std::min(lowestKept, it->first);
        continue;
      }
      pixelSetsHeld_ -= traced.tasks.size();
      traced.tasks = {};
    }
  }
  pixelsForgottenBelow_ = lowestKept;
}

std::set<int> TracerLedger::FramesReachedBy(const std::string& worker, int frameCount) const {
  std::set<int> reached;
  for (const auto& [frame, workers] : frames_) {
    auto traced = workers.find(worker);
    if (traced == workers.end()) continue;
    // A horizon is at most frame + window + 1, "valid through the window": copies reach
    // frame + window at the furthest.
    for (int f = frame; f <= frame + traced->second.window && f < frameCount; ++f) reached.insert(f);
  }
  return reached;
}

}  // namespace tcfarm
