#include "coordinator/dispatch/worker_registry.h"

namespace tcfarm {
namespace {

std::vector<uint64_t> TasksOf(const WorkerState& worker) {
  return {worker.inFlight.begin(), worker.inFlight.end()};
}

}  // namespace

std::vector<uint64_t> WorkerRegistry::OnReady(const std::string& identity,
                                              const wire::Ready& ready, const std::string& principal,
                                              SteadyTime now) {
  std::vector<uint64_t> lost;
  auto it = workers_.find(identity);
  if (it != workers_.end()) lost = TasksOf(it->second);
  WorkerState& worker = workers_[identity];
  worker = WorkerState{};
  worker.identity = identity;
  worker.principal = principal;
  worker.name = ready.name;
  worker.capacity = std::max<uint32_t>(1, ready.capacity);
  worker.threads = std::max<uint32_t>(1, ready.threads);
  worker.connectedAt = worker.lastHeard = now;
  return lost;
}

bool WorkerRegistry::OnHeard(const std::string& identity, SteadyTime now) {
  WorkerState* worker = Find(identity);
  if (!worker) return false;
  worker->lastHeard = now;
  return true;
}

std::vector<WorkerRegistry::Expired> WorkerRegistry::ExpireSilent(SteadyTime now) {
  std::vector<Expired> expired;
  for (auto it = workers_.begin(); it != workers_.end();) {
    if (now - it->second.lastHeard < policy_.timeout) {
      ++it;
      continue;
    }
    expired.push_back({it->second.name, std::vector<uint64_t>(it->second.inFlight.begin(), it->second.inFlight.end())});
    it = workers_.erase(it);
  }
  return expired;
}

std::vector<uint64_t> WorkerRegistry::Remove(const std::string& identity) {
  auto it = workers_.find(identity);
  if (it == workers_.end()) return {};
  std::vector<uint64_t> lost = TasksOf(it->second);
  workers_.erase(it);
  return lost;
}

WorkerState* WorkerRegistry::MostAvailable(const std::set<std::string>& skip) {
  WorkerState* best = nullptr;
  for (auto& [identity, worker] : workers_) {
    if (worker.FreeCredit() == 0 || skip.count(identity)) continue;
    if (!best || worker.FreeCredit() > best->FreeCredit() ||
        (worker.FreeCredit() == best->FreeCredit() && worker.lastAssigned > best->lastAssigned)) {
      best = &worker;
    }
  }
  return best;
}

void WorkerRegistry::Assign(const std::string& identity, uint64_t taskId) {
  if (WorkerState* worker = Find(identity)) {
    worker->inFlight.insert(taskId);
    worker->lastAssigned = ++assignments_;
  }
}

bool WorkerRegistry::Release(const std::string& identity, uint64_t taskId) {
  WorkerState* worker = Find(identity);
  return worker && worker->inFlight.erase(taskId) > 0;
}

std::string WorkerRegistry::Forget(uint64_t taskId) {
  for (auto& [identity, worker] : workers_) {
    if (worker.inFlight.erase(taskId)) return identity;
  }
  return "";
}

std::vector<std::string> WorkerRegistry::IdentitiesOf(const std::string& principal) const {
  std::vector<std::string> identities;
  for (const auto& [identity, worker] : workers_) {
    if (worker.principal == principal) identities.push_back(identity);
  }
  return identities;
}

WorkerState* WorkerRegistry::Find(const std::string& identity) {
  auto it = workers_.find(identity);
  return it == workers_.end() ? nullptr : &it->second;
}

const WorkerState* WorkerRegistry::Find(const std::string& identity) const {
  auto it = workers_.find(identity);
  return it == workers_.end() ? nullptr : &it->second;
}

size_t WorkerRegistry::TotalFreeCredit() const {
  size_t credit = 0;
  for (const auto& [identity, worker] : workers_) credit += worker.FreeCredit();
  return credit;
}

}  // namespace tcfarm
