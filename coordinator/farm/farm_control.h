// What the HTTP API may ask of the running farm, beside the job store: cancel a job,
// change a running job's priority, let go of a job about to be deleted, and read a
// snapshot of workers and of running jobs' live figures. Thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/worker_bans.h"

namespace tcfarm {

struct WorkerSnapshot {
  std::string name;
  std::string principal;  // who it is beyond this connection (its CURVE key, or name@address)
  uint32_t capacity = 0, threads = 0, inFlight = 0;
  uint64_t tasksDone = 0, pixelsDone = 0;
  double traceSeconds = 0;
  double secondsSinceHeard = 0;
  double connectedSeconds = 0;
};

struct FarmSnapshot {
  std::vector<WorkerSnapshot> workers;
  std::map<uint64_t, nlohmann::json> runningStats;  // live "stats" of running jobs, by job id
  // Per running job, the frames it is working on (ascending, the scene's numbers): tasks
  // queued or in flight for them, or finished and being written.
  std::map<uint64_t, std::vector<int>> tracingFrames;
  size_t queuedTasks = 0, inFlightTasks = 0;
};

class FarmControl {
 public:
  virtual ~FarmControl() = default;
  // The job is already marked canceled in the store; this stops its work now.
  virtual void RequestCancel(uint64_t jobId) = 0;
  // The store holds the job's new priority; a running job's next tasks follow it.
  virtual void RequestPriority(uint64_t jobId, int priority) = 0;
  // The job is final in the store (or gone) and its files are about to be removed: the
  // farm stops every use of them (a run a cancel has not reached yet, the frame finisher).
  // Returns once nothing of the farm touches the job's folder; false when the farm has
  // stopped and cannot promise that.
  virtual bool ReleaseJob(uint64_t jobId) = 0;
  virtual FarmSnapshot Snapshot() const = 0;
  // Workers banned for returning wrong values (farm/worker_bans.h), and lifting a ban:
  // false when the principal was not banned.
  virtual std::vector<WorkerBan> Bans() const = 0;
  virtual bool LiftBan(const std::string& principal) = 0;
};

}  // namespace tcfarm
