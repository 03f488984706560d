#include "coordinator/farm/farm_requests.h"

namespace tcfarm {

void FarmRequests::Cancel(uint64_t jobId) {
  std::lock_guard<std::mutex> lock(mutex_);
  asked_.cancels.insert(jobId);
}

void FarmRequests::SetPriority(uint64_t jobId, int priority) {
  std::lock_guard<std::mutex> lock(mutex_);
  asked_.priorities[jobId] = priority;
}

void FarmRequests::LiftBan(const std::string& principal) {
  std::lock_guard<std::mutex> lock(mutex_);
  asked_.liftedBans.push_back(principal);
}

bool FarmRequests::Release(uint64_t jobId) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (stopped_) return false;
  const uint64_t ticket = nextReleaseTicket_++;
  asked_.releases.emplace_back(jobId, ticket);
  releasesOwed_.insert(ticket);
  released_.wait(lock, [&] { return stopped_ || !releasesOwed_.count(ticket); });
  return releasesOwed_.erase(ticket) == 0;  // still owed: the loop stopped first
}

FarmRequests::Batch FarmRequests::Take() {
  std::lock_guard<std::mutex> lock(mutex_);
  Batch taken;
  std::swap(taken, asked_);
  return taken;
}

void FarmRequests::Settle(const std::vector<ReleaseTicket>& releases, const std::set<uint64_t>& unread) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [id, ticket] : releases) {
      if (unread.count(id)) {
        asked_.releases.emplace_back(id, ticket);
      } else {
        releasesOwed_.erase(ticket);
      }
    }
    for (uint64_t id : unread) asked_.cancels.insert(id);
  }
  if (!releases.empty()) released_.notify_all();
}

void FarmRequests::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
  }
  released_.notify_all();
}

void FarmRequests::Publish(FarmSnapshot snapshot) {
  std::lock_guard<std::mutex> lock(mutex_);
  snapshot_ = std::move(snapshot);
}

FarmSnapshot FarmRequests::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return snapshot_;
}

}  // namespace tcfarm
