// The dispatcher's tasks: those waiting for a worker, queued per job, and those in flight
// with one. Jobs share the workers by stride scheduling weighted by priority, so a long
// job cannot starve a short one; a task never goes to a worker that answered ERROR for it
// nor to one whose principal it avoids. It knows nothing of sockets or workers' credit:
// the dispatcher asks it for the next task a worker may take and says where it went.
//
// Not thread-safe: the dispatcher's thread owns it.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "coordinator/dispatch/worker_registry.h"
#include "proto/pixel_set/pixel_set.h"
#include "proto/wire/liveness.h"

namespace tcfarm {

struct DispatchTask {
  uint64_t jobId = 0;
  uint64_t plannerTaskId = 0;
  int frame = 0;  // absolute frame number (the scene's)
  PixelSet pixels;
  int window = 0;
  // Workers (principals, see PrincipalOf) it must not go to: a check is worth something
  // only when someone other than the worker whose values it checks traces it. A rule:
  // a check by the worker it checks proves nothing, so such a task waits for someone
  // else, and where nobody else is connected it is handed back (TakeStranded).
  std::set<std::string> avoid;
  // A check or repair the coordinator's referee may trace when no connected worker may
  // (TakeStranded); planner tasks never go to the referee.
  bool refereeMayTrace = false;
};

class TaskQueue {
 public:
  struct Entry {
    DispatchTask task;
    bool pending = true;
    SteadyTime sentAt;
    std::string holder;              // the worker it is in flight with; "" while pending
    std::set<std::string> failedBy;  // workers that answered ERROR for it: not sent there again
    std::string firstError;
  };
  // What every task of a job shares.
  struct Job {
    double weight = 1;  // WeightOf(its priority)
    double pass = 0;    // stride scheduling: the job with the lowest pass goes next
    uint32_t width = 0, height = 0;
    std::string sceneHash;
    std::deque<uint64_t> pending;
  };

  // A job of priority p >= 0 gets 1 + p shares, one of p < 0 gets 1 / (1 - p).
  static double WeightOf(int priority);
  // Whether `worker` may take the task: never one it answered ERROR for, nor one that
  // avoids its principal.
  static bool MayTake(const Entry& entry, const WorkerState& worker);

  void AddJob(uint64_t jobId, int priority, uint32_t width, uint32_t height, const std::string& sceneHash);
  void SetPriority(uint64_t jobId, int priority);
  // Drops the job and all its tasks, pending and in flight; returns the ids of the tasks
  // dropped (none for an unknown job).
  std::vector<uint64_t> RemoveJob(uint64_t jobId);
  bool HasJob(uint64_t jobId) const { return jobs_.count(jobId) > 0; }
  const Job& JobOf(uint64_t jobId) const { return jobs_.at(jobId); }
  bool SceneUsed(const std::string& sceneHash) const;

  // Queues the task at the back of its job's queue; ignored for a job not added.
  void Enqueue(DispatchTask task);
  // The next task `worker` may take (stride order over jobs, skipping tasks it may not
  // take), taken off its job's queue but still counted pending until Sent; 0 when there
  // is none for it.
  uint64_t TakeFor(const WorkerState& worker);
  // The task taken by TakeFor is now in flight with `holder`, sent at `now`.
  Entry& Sent(uint64_t taskId, const std::string& holder, SteadyTime now);
  // In-flight tasks back to the front of their jobs' queues (they waited long enough
  // already); returns how many of each job went back. Unknown and pending ids are skipped.
  std::map<uint64_t, size_t> Requeue(const std::vector<uint64_t>& taskIds);
  // Pending tasks that may go to the referee and that `anyoneMayTake` says no connected
  // worker may, taken off the queue.
  std::vector<DispatchTask> TakeStranded(const std::function<bool(const Entry&)>& anyoneMayTake);

  Entry* Find(uint64_t taskId);
  void Erase(uint64_t taskId) { tasks_.erase(taskId); }
  size_t Pending() const { return pendingCount_; }
  size_t InFlight() const { return tasks_.size() - pendingCount_; }

 private:
  std::unordered_map<uint64_t, Entry> tasks_;
  std::map<uint64_t, Job> jobs_;
  uint64_t nextTaskId_ = 1;
  size_t pendingCount_ = 0;
};

}  // namespace tcfarm
