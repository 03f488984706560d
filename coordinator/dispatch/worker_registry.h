// The coordinator's view of its workers: who is connected, how much credit each has,
// which tasks each holds, and who has gone silent. Pure bookkeeping with an injected
// clock; the dispatcher does the socket I/O.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "proto/wire/liveness.h"
#include "proto/wire/wire.h"

namespace tcfarm {

struct WorkerState {
  std::string identity;  // the ROUTER's routing id for this connection
  // Who it is beyond this connection (PrincipalOf): what checks avoid and bans name, so
  // that reconnecting does not make a worker someone else.
  std::string principal;
  std::string name;
  uint32_t capacity = 1;  // tasks it accepts in flight (its credit)
  uint32_t threads = 1;
  SteadyTime connectedAt;
  SteadyTime lastHeard;
  std::set<uint64_t> inFlight;
  uint64_t tasksDone = 0;
  uint64_t lastAssigned = 0;  // the registry's serial of the last task given to it; 0: none
  uint64_t pixelsDone = 0;
  double traceSeconds = 0;
  uint32_t FreeCredit() const {
    return inFlight.size() >= capacity ? 0 : capacity - static_cast<uint32_t>(inFlight.size());
  }
};

class WorkerRegistry {
 public:
  explicit WorkerRegistry(HeartbeatPolicy policy) : policy_(policy) {}

  // READY. A worker that says READY again has restarted its connection state: whatever
  // it held is lost and returned for requeueing.
  std::vector<uint64_t> OnReady(const std::string& identity, const wire::Ready& ready,
                                const std::string& principal, SteadyTime now);
  // Any message: refreshes liveness. False for an identity that never said READY.
  bool OnHeard(const std::string& identity, SteadyTime now);
  // Workers silent past the timeout are forgotten; their names and tasks are returned.
  struct Expired {
    std::string name;
    std::vector<uint64_t> tasks;
  };
  std::vector<Expired> ExpireSilent(SteadyTime now);
  // DISCONNECT: the worker leaves; its tasks are returned.
  std::vector<uint64_t> Remove(const std::string& identity);

  // The worker with the most free credit, or nullptr when every worker is full. Ties go
  // to the worker given a task last: its caches are warm (the scene built, its pages
  // touched, the frame's top-level scene made), and a job that cannot use the whole farm
  // keeps to the workers it has warmed instead of paying a cold start on every one.
  // Workers in `skip` are passed over.
  WorkerState* MostAvailable(const std::set<std::string>& skip = {});
  void Assign(const std::string& identity, uint64_t taskId);
  // Returns the credit of a finished (or failed) task; false if that worker did not hold it.
  bool Release(const std::string& identity, uint64_t taskId);
  // Forgets a task wherever it is held (its job went away); the credit returns at once.
  // Returns the identity of the worker that held it, "" when none did.
  std::string Forget(uint64_t taskId);

  // Connections of the principal (a worker may hold several at once).
  std::vector<std::string> IdentitiesOf(const std::string& principal) const;
  WorkerState* Find(const std::string& identity);
  const WorkerState* Find(const std::string& identity) const;
  const std::map<std::string, WorkerState>& workers() const { return workers_; }
  size_t TotalFreeCredit() const;

 private:
  uint64_t assignments_ = 0;  // tasks assigned so far: the serial of the next minus one
  HeartbeatPolicy policy_;
  std::map<std::string, WorkerState> workers_;
};

}  // namespace tcfarm
