// Which queued jobs the farm's memory admits (FarmOptions::farmMemoryBytes): a job is
// claimed once its need, estimated from its request (JobMemoryBytes), fits in what the
// running jobs leave, with as many bins at once as fit. A job held back is remembered
// with when it started waiting; once it has waited longestWait no later job may pass it,
// so the memory drains to it as running jobs end.
//
// One look over the queue (ClaimJobs) is BeginLook, Admits per job, EndLook: jobs not seen
// held back in a look are forgotten. Owned by the farm loop; not thread-safe.
#pragma once

#include <cstdint>
#include <map>

#include "coordinator/jobs/job_store.h"
#include "proto/wire/liveness.h"

namespace tcfarm {

struct MemoryBudget {
  uint64_t farmMemoryBytes = 0;    // for all running jobs together; 0: no limit
  uint64_t pendingFrameBytes = 0;  // each job's memory for frames ahead of their turn
  Milliseconds longestWait{5 * 60 * 1000};
};

class MemoryAdmission {
 public:
  MemoryAdmission(MemoryBudget budget, const Clock& clock) : budget_(budget), clock_(clock) {}

  void BeginLook() { waitingNow_.clear(); }
  // Whether the job fits beside running jobs that were given `used` bytes; if so, what it
  // is given as *granted (untouched without a limit). A job that would not fit even alone
  // is admitted with the whole budget, to fail with its shortfall rather than wait
  // forever. Otherwise it waits, and *passable says whether later jobs may still pass it.
  bool Admits(const JobRecord& job, uint64_t used, uint64_t* granted, bool* passable);
  void EndLook() { waiting_.swap(waitingNow_); }

 private:
  MemoryBudget budget_;
  const Clock& clock_;
  std::map<uint64_t, SteadyTime> waiting_;     // held back by the last look, since when
  std::map<uint64_t, SteadyTime> waitingNow_;  // held back by this look
};

}  // namespace tcfarm
