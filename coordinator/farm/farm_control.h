// What the HTTP API may ask of the running farm, beside the job store: cancel a job,
// and read a snapshot of workers and of running jobs' live figures. Thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tcfarm {

struct WorkerSnapshot {
  std::string name;
  uint32_t capacity = 0, threads = 0, inFlight = 0;
  uint64_t tasksDone = 0, pixelsDone = 0;
  double traceSeconds = 0;
  double secondsSinceHeard = 0;
  double connectedSeconds = 0;
};

struct FarmSnapshot {
  std::vector<WorkerSnapshot> workers;
  std::map<uint64_t, nlohmann::json> runningStats;  // live "stats" of running jobs, by job id
  size_t queuedTasks = 0, inFlightTasks = 0;
};

class FarmControl {
 public:
  virtual ~FarmControl() = default;
  // The job is already marked canceled in the store; this stops its work now.
  virtual void RequestCancel(uint64_t jobId) = 0;
  virtual FarmSnapshot Snapshot() const = 0;
};

}  // namespace tcfarm
