// Everything that frees room in the store, in one place, so that DELETE /api/v1/jobs/{id}
// and the retention (--keep-days, --store-budget) delete a job by the same code:
//
//  - Delete: a finished job's record and events (JobStore::Delete), then its folder
//    (frames, masks, previews), and the assets (STORE/assets/<sha256>) no remaining job
//    names. The farm lets go of the job first (its frame finisher may be encoding the
//    job's frames), so nothing writes into the folder while it is removed, or after.
//  - The store's size, for /metrics (tcfarm_store_bytes): measured by walking the store
//    at most every kUsageIntervalMs (less often for a store that takes long to walk),
//    lowered at once by what each deletion freed, so a scrape never walks a large tree.
//  - Retention, when asked for: at start and every kRetentionIntervalMs, finished jobs
//    that finished longer than keep ago are deleted, and while the store is larger than
//    its budget the earliest finished jobs are deleted until it fits.
//  - Orphan assets: every kOrphanIntervalMs (or the grace period, when shorter), uploaded
//    assets that no job names and that are older than RetentionPolicy::orphanAssetGraceMs
//    are removed: uploads of a submission that never came (refused, or its client gone).
//    The grace period is the time a client has between uploading and submitting; asking
//    which assets are missing, or uploading one again, starts it anew (AssetStore::Freshen).
//  - Deletions a previous process left half done (the record gone, the folder not) are
//    finished at start.
//
// Time comes from an injected clock (unix milliseconds): RunDue does what is due at that
// time, so tests need no sleeps; Start runs it on a thread once a second.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "coordinator/jobs/job_store.h"

namespace prometheus {
class Counter;
class Gauge;
class Registry;
}  // namespace prometheus

namespace tcfarm {

struct RetentionPolicy {
  static constexpr int64_t kDefaultOrphanAssetGraceMs = 3600 * 1000;

  std::optional<int64_t> keepMs;        // finished jobs that finished longer ago go
  std::optional<uint64_t> budgetBytes;  // the store's size beyond which the earliest finished jobs go
  // An asset no job names goes once it is older than this (--asset-orphan-grace-s).
  int64_t orphanAssetGraceMs = kDefaultOrphanAssetGraceMs;
  bool Active() const { return keepMs.has_value() || budgetBytes.has_value(); }
};

// "50G", "500M", "1.5T", "2GiB", "1000000": bytes, in binary multiples (K = 1024). Throws
// std::invalid_argument saying what was expected.
uint64_t ParseByteSize(const std::string& text);
// "12.3 MiB": bytes for people.
std::string ShowBytes(uint64_t bytes);

// The farm could not let go of a job to delete (it is stopping): nothing was changed.
class FarmStoppingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StoreJanitor {
 public:
  static constexpr int64_t kRetentionIntervalMs = 60'000;
  // Often enough that the gauge follows a running job's frames, rarely enough that a store
  // of a million files is not walked all the time: a walk that took longer waits
  // kUsageWalkShare times its own duration, so walking never takes more than 5 % of a core.
  static constexpr int64_t kUsageIntervalMs = 10'000;
  static constexpr int kUsageWalkShare = 20;
  static constexpr int64_t kOrphanIntervalMs = 60'000;

  // releaseJob: the farm lets go of a job's files (FarmControl::ReleaseJob); false when it
  // cannot promise that (it has stopped). metrics: where tcfarm_store_bytes and
  // tcfarm_jobs_deleted_total are registered (none: not exported).
  StoreJanitor(JobStore& jobs, std::filesystem::path storeRoot, std::function<bool(uint64_t)> releaseJob,
               prometheus::Registry* metrics, RetentionPolicy policy = {},
               JobStore::ClockMs nowMs = JobStore::SystemNowMs);
  ~StoreJanitor();
  StoreJanitor(const StoreJanitor&) = delete;
  StoreJanitor& operator=(const StoreJanitor&) = delete;

  struct Deletion {
    DeletedJob::Outcome outcome = DeletedJob::Outcome::kNotFound;
    JobState state = JobState::kQueued;  // the job's state (the one that kept it, for kActive)
    uint64_t freedBytes = 0;             // its folder's files and its unshared assets
  };
  // Thread-safe. kActive (nothing changed) for a queued or running job, kNotFound for an
  // unknown one. Throws JobStoreError from the database, and FarmStoppingError when the farm
  // cannot let go of the job (nothing changed then either). reason: said in the job's
  // "deleted" event ("deleted by DELETE", "by retention: ...").
  Deletion Delete(uint64_t id, const std::string& reason = "on request");

  // A submission holds this from the moment it checks its assets until its job is
  // stored: an asset it names is not removed in between by a deletion.
  std::shared_lock<std::shared_mutex> HoldAssets() { return std::shared_lock<std::shared_mutex>(assets_); }

  // What is due now: the first call measures the store, finishes deletions left half
  // done and applies the retention; later calls measure every kUsageIntervalMs and apply
  // the retention every kRetentionIntervalMs. Errors are logged; the next call tries again.
  void RunDue();
  // Runs RunDue on a thread, once a second, until Stop (or the destructor).
  void Start();
  void Stop();

  uint64_t StoreBytes() const { return storeBytes_; }
  uint64_t JobsDeleted() const { return jobsDeleted_; }
  uint64_t OrphanAssetsRemoved() const { return orphansRemoved_; }

 private:
  void Measure();
  void FinishPendingDeletions();
  void ApplyRetention(int64_t nowMs);
  // The folder's files, removed; the bytes they held. nullopt when some could not be
  // removed (the error is logged).
  std::optional<uint64_t> RemoveFolder(uint64_t id);
  uint64_t RemoveAssets(const std::vector<std::string>& hashes);
  // Assets older than the grace period that no job names, removed; logged and counted.
  void RemoveOrphanAssets(int64_t nowMs);
  void Freed(uint64_t bytes);

  JobStore& jobs_;
  std::filesystem::path root_;
  std::function<bool(uint64_t)> releaseJob_;
  RetentionPolicy policy_;
  JobStore::ClockMs nowMs_;
  std::shared_mutex assets_;  // shared: submissions; exclusive: a deletion removing assets
  std::atomic<uint64_t> storeBytes_{0};
  std::atomic<uint64_t> jobsDeleted_{0};
  std::atomic<uint64_t> orphansRemoved_{0};
  prometheus::Counter* orphansRemovedCounter_ = nullptr;
  prometheus::Counter* orphanBytesRemovedCounter_ = nullptr;
  prometheus::Gauge* storeBytesGauge_ = nullptr;
  prometheus::Counter* jobsDeletedCounter_ = nullptr;

  std::mutex dueMutex_;  // one RunDue at a time
  std::optional<int64_t> lastMeasureMs_, lastRetentionMs_, lastOrphanSweepMs_;
  int64_t measureIntervalMs_ = kUsageIntervalMs;
  bool overBudgetLogged_ = false;

  std::mutex threadMutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace tcfarm
