// Worker processes started by the coordinator itself for the embedded local farm. They
// are ordinary `tcfarm-worker serve` processes on loopback; one that exits is restarted,
// so a local farm heals the way a cluster's orchestrator would heal it. They die with the
// coordinator, even one killed with SIGKILL: each asks the kernel (PR_SET_PDEATHSIG) for
// SIGKILL when the thread that started it exits. So Start and RestartExited are called
// from a thread that lives as long as the coordinator: the main thread, which runs the farm.
#pragma once

#include <sys/types.h>

#include <functional>
#include <string>
#include <vector>

namespace tcfarm {

class LocalWorkers {
 public:
  // Arguments added to worker `index`'s command line (its own CURVE keys).
  using ArgumentsFor = std::function<std::vector<std::string>(unsigned index)>;
  LocalWorkers(std::string binary, std::string coordinatorEndpoint, unsigned threadsEach,
               ArgumentsFor extraArguments = {});
  ~LocalWorkers();  // stops them

  void Start(unsigned count);
  // Restarts workers that have exited; returns how many were restarted.
  int RestartExited();
  // SIGTERM, then SIGKILL for those still running after a grace period.
  void Stop();
  size_t size() const { return pids_.size(); }

 private:
  pid_t Spawn(unsigned index) const;

  std::string binary_;
  std::string endpoint_;
  unsigned threadsEach_;
  ArgumentsFor extraArguments_;
  std::vector<pid_t> pids_;
};

// The tcfarm-worker binary beside this executable, or in the build tree's worker/
// folder, or on PATH as a last resort.
std::string FindWorkerBinary();

}  // namespace tcfarm
