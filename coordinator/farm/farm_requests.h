// What other threads (the HTTP server) ask of the farm loop, and what the loop publishes
// back: cancels, priority changes, lifted bans and job releases wait here until the loop
// takes them (Take); the loop's latest snapshot waits here for readers (Snapshot).
// Thread-safe: one mutex guards it all, and no call holds it while the loop works.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "coordinator/farm/farm_control.h"

namespace tcfarm {

class FarmRequests {
 public:
  // A release: the job, and the ticket its waiting caller holds.
  using ReleaseTicket = std::pair<uint64_t, uint64_t>;
  // Everything asked since the last Take.
  struct Batch {
    std::set<uint64_t> cancels;
    std::map<uint64_t, int> priorities;  // the latest per job
    std::vector<ReleaseTicket> releases;
    std::vector<std::string> liftedBans;  // lifted in the store, not yet in the dispatcher
  };

  void Cancel(uint64_t jobId);
  void SetPriority(uint64_t jobId, int priority);
  void LiftBan(const std::string& principal);
  // Asks the loop to let go of the job and waits until it has (Settle); false when the
  // loop stopped (Stop) before it did, or had stopped already.
  bool Release(uint64_t jobId);

  // The loop's side: takes what was asked, leaving nothing behind.
  Batch Take();
  // The loop handled `releases` (taken by Take), except those of jobs in `unread`, whose
  // state it could not read: those and the cancels of `unread` are asked again by the
  // next Take. Wakes the callers whose releases are done.
  void Settle(const std::vector<ReleaseTicket>& releases, const std::set<uint64_t>& unread);
  // The loop ended: every waiting Release returns false, and later ones at once.
  void Stop();

  void Publish(FarmSnapshot snapshot);
  FarmSnapshot Snapshot() const;

 private:
  mutable std::mutex mutex_;
  Batch asked_;
  uint64_t nextReleaseTicket_ = 1;
  std::set<uint64_t> releasesOwed_;  // tickets asked for and not done
  bool stopped_ = false;             // nobody answers requests any more
  std::condition_variable released_;
  FarmSnapshot snapshot_;
};

}  // namespace tcfarm
