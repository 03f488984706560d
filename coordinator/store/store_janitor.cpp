#include "coordinator/store/store_janitor.h"

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/registry.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <set>
#include <system_error>

#include "proto/metrics/metric_builders.h"
#include "coordinator/store/asset_store.h"
#include "coordinator/store/frame_store.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

constexpr double kDayMs = 24 * 3600 * 1000.0;
// A removal that meets a file created meanwhile (a preview made on request) tries again.
constexpr int kRemoveAttempts = 3;

// Bytes of the regular files under `folder`; files that vanish meanwhile count nothing.
uint64_t BytesUnder(const fs::path& folder) {
  uint64_t bytes = 0;
  std::error_code error;
  for (fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied, error), end;
       !error && it != end; it.increment(error)) {
    std::error_code ignored;
    if (it->is_regular_file(ignored)) {
      const uintmax_t size = it->file_size(ignored);
      if (!ignored) bytes += size;
    }
  }
  return bytes;
}

}  // namespace

uint64_t ParseByteSize(const std::string& text) {
  const std::string expected = "expected a size such as 500M, 50G or 2T (K, M, G, T: powers of 1024; no unit: bytes)";
  size_t used = 0;
  double number = -1;
  try {
    number = std::stod(text, &used);
  } catch (const std::exception&) {
    throw std::invalid_argument("\"" + text + "\" is not a size; " + expected);
  }
  std::string unit = text.substr(used);
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return std::toupper(c); });
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();  // "GB", "GIB"
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  static const std::string kUnits = "BKMGT";
  const size_t power = unit.empty() ? 0 : kUnits.find(unit);
  if (!std::isfinite(number) || number < 0 || !std::isdigit(static_cast<unsigned char>(text[0])) ||
      unit.size() > 1 || power == std::string::npos) {
    throw std::invalid_argument("\"" + text + "\" is not a size; " + expected);
  }
  const double bytes = number * std::pow(1024.0, static_cast<double>(power));
  if (bytes >= 1.8e19) throw std::invalid_argument("\"" + text + "\" is too large; " + expected);
  return static_cast<uint64_t>(bytes);
}

std::string ShowBytes(uint64_t bytes) {
  static const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
  double value = static_cast<double>(bytes);
  size_t unit = 0;
  while (value >= 1024 && unit + 1 < std::size(kUnits)) {
    value /= 1024;
    ++unit;
  }
  char text[32];
  std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.1f %s", value, kUnits[unit]);
  return text;
}

StoreJanitor::StoreJanitor(JobStore& jobs, fs::path storeRoot, std::function<bool(uint64_t)> releaseJob,
                           prometheus::Registry* metrics, RetentionPolicy policy, JobStore::ClockMs nowMs)
    : jobs_(jobs),
      root_(std::move(storeRoot)),
      releaseJob_(std::move(releaseJob)),
      policy_(policy),
      nowMs_(std::move(nowMs)) {
  if (metrics) {
    storeBytesGauge_ = &NewGauge(*metrics, "tcfarm_store_bytes",
                                 "Bytes in the store (frames, masks, previews, assets): measured at most every 10 s, "
                                 "lowered at once by each deletion.");
    jobsDeletedCounter_ = &NewCounter(*metrics, "tcfarm_jobs_deleted_total",
                                      "Jobs deleted with their files, on request (DELETE) or by the retention.");
    orphansRemovedCounter_ = &NewCounter(*metrics, "tcfarm_store_orphan_assets_removed_total",
                                         "Uploaded assets removed because no job named them within the grace period.");
    orphanBytesRemovedCounter_ = &NewCounter(*metrics, "tcfarm_store_orphan_asset_bytes_removed_total",
                                             "Bytes of the orphan assets removed.");
  }
}

StoreJanitor::~StoreJanitor() { Stop(); }

StoreJanitor::Deletion StoreJanitor::Delete(uint64_t id, const std::string& reason) {
  Deletion deletion;
  const std::optional<JobState> state = jobs_.StateOf(id);
  if (!state) return deletion;
  deletion.state = *state;
  if (*state == JobState::kQueued || *state == JobState::kRunning) {
    deletion.outcome = DeletedJob::Outcome::kActive;
    return deletion;
  }
  // The farm lets go first, before anything changes: a job canceled a moment ago may
  // still have frames being written, a finished one frames being compressed.
  if (!releaseJob_(id)) {
    throw FarmStoppingError("the coordinator is stopping; job " + std::to_string(id) + " was not deleted");
  }
  DeletedJob deleted;
  {
    std::unique_lock<std::shared_mutex> lock(assets_);
    deleted = jobs_.Delete(id);
    if (deleted.outcome == DeletedJob::Outcome::kDeleted) deletion.freedBytes += RemoveAssets(deleted.unreferencedAssets);
  }
  deletion.outcome = deleted.outcome;
  deletion.state = deleted.state;
  if (deleted.outcome != DeletedJob::Outcome::kDeleted) return deletion;  // retried meanwhile, or deleted twice
  // Once more, now that no record can bring the job back to the farm (a retry, a claim
  // and a cancel between the first release and the record's deletion). A farm stopped
  // meanwhile leaves the folder to the note JobStore::Delete made, for the next start.
  if (releaseJob_(id)) {
    const std::optional<uint64_t> folder = RemoveFolder(id);
    deletion.freedBytes += folder.value_or(0);
    // A folder not removed whole keeps its note: the next start tries again.
    if (folder) {
      jobs_.FinishDeletion(id, {"deleted", "deleted " + reason + "; " + ShowBytes(deletion.freedBytes) + " freed",
                                {{"freed_bytes", deletion.freedBytes}, {"reason", reason}}});
    }
  }
  ++jobsDeleted_;
  if (jobsDeletedCounter_) jobsDeletedCounter_->Increment();
  Freed(deletion.freedBytes);
  return deletion;
}

std::optional<uint64_t> StoreJanitor::RemoveFolder(uint64_t id) {
  const fs::path folder = FrameStore(root_).JobFolder(id);
  uint64_t freed = 0;
  for (int attempt = 0; attempt < kRemoveAttempts; ++attempt) {
    std::error_code error;
    if (!fs::exists(folder, error)) return freed;
    freed += BytesUnder(folder);
    fs::remove_all(folder, error);
    if (!error) return freed;
    if (attempt + 1 == kRemoveAttempts) {
      std::fprintf(stderr, "coordinator: job %llu's folder %s could not be removed whole: %s\n",
                   static_cast<unsigned long long>(id), folder.c_str(), error.message().c_str());
    }
  }
  return std::nullopt;
}

uint64_t StoreJanitor::RemoveAssets(const std::vector<std::string>& hashes) {
  const AssetStore assets(root_ / "assets");
  uint64_t freed = 0;
  for (const std::string& hash : hashes) {
    if (!IsAssetHash(hash)) continue;  // a name the store never gave a file
    const std::optional<uint64_t> size = assets.SizeOf(hash);
    std::error_code error;
    if (size && fs::remove(assets.PathOf(hash), error)) freed += *size;
  }
  return freed;
}

void StoreJanitor::RemoveOrphanAssets(int64_t nowMs) {
  const AssetStore assets(root_ / "assets");
  const int64_t bornBeforeMs = nowMs - policy_.orphanAssetGraceMs;
  const std::vector<std::string> old = assets.OlderThan(bornBeforeMs);
  if (old.empty()) return;
  // Exclusive, as a deletion's: a submission between checking its assets and storing its
  // job holds them shared, so an asset it names is either named by then or not yet checked.
  std::unique_lock<std::shared_mutex> lock(assets_);
  const std::set<std::string> named = jobs_.NamedAssets(old);
  uint64_t count = 0, bytes = 0;
  for (const std::string& hash : old) {
    // Freshened meanwhile (asked about or uploaded again): a submission is on its way.
    if (named.count(hash) != 0 || !assets.OlderThan(bornBeforeMs, hash)) continue;
    const std::optional<uint64_t> size = assets.SizeOf(hash);
    std::error_code error;
    if (size && fs::remove(assets.PathOf(hash), error)) {
      ++count;
      bytes += *size;
    }
  }
  lock.unlock();
  if (count == 0) return;
  std::fprintf(stderr, "coordinator: removed %llu uploaded assets (%s) that no job named within %lld s\n",
               static_cast<unsigned long long>(count), ShowBytes(bytes).c_str(),
               static_cast<long long>(policy_.orphanAssetGraceMs / 1000));
  orphansRemoved_ += count;
  if (orphansRemovedCounter_) {
    orphansRemovedCounter_->Increment(static_cast<double>(count));
    orphanBytesRemovedCounter_->Increment(static_cast<double>(bytes));
  }
  Freed(bytes);
}

void StoreJanitor::Freed(uint64_t bytes) {
  uint64_t now = storeBytes_.load();
  while (!storeBytes_.compare_exchange_weak(now, now - std::min(now, bytes))) {
  }
  if (storeBytesGauge_) storeBytesGauge_->Set(static_cast<double>(storeBytes_.load()));
}

void StoreJanitor::Measure() {
  const auto start = std::chrono::steady_clock::now();
  storeBytes_ = BytesUnder(root_);
  if (storeBytesGauge_) storeBytesGauge_->Set(static_cast<double>(storeBytes_.load()));
  const auto walk = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - start);
  measureIntervalMs_ = std::max<int64_t>(kUsageIntervalMs, kUsageWalkShare * walk.count());
}

void StoreJanitor::FinishPendingDeletions() {
  for (uint64_t id : jobs_.PendingDeletions()) {
    if (!releaseJob_(id)) return;
    const std::optional<uint64_t> freed = RemoveFolder(id);
    if (!freed) continue;
    jobs_.FinishDeletion(id, {"deleted", "deleted; its folder removed at start, " + ShowBytes(*freed) + " freed",
                              {{"freed_bytes", *freed}, {"reason", "a deletion the previous coordinator left unfinished"}}});
    Freed(*freed);
  }
}

void StoreJanitor::ApplyRetention(int64_t nowMs) {
  if (policy_.keepMs) {
    char days[32];
    std::snprintf(days, sizeof days, "%g", static_cast<double>(*policy_.keepMs) / kDayMs);
    const std::string reason = std::string("by the retention: finished more than ") + days + " days ago (--keep-days)";
    for (uint64_t id : jobs_.FinishedJobs(nowMs - *policy_.keepMs)) Delete(id, reason);
  }
  if (policy_.budgetBytes) {
    // The budget is weighed against the store as it is, not as last measured (RunDue may
    // have measured it this very round).
    if (lastMeasureMs_ != nowMs) {
      lastMeasureMs_ = nowMs;
      Measure();
    }
    if (storeBytes_ <= *policy_.budgetBytes) {
      overBudgetLogged_ = false;
      return;
    }
    const std::string reason = "by the retention: the store was larger than its budget of " +
                               ShowBytes(*policy_.budgetBytes) + " (--store-budget)";
    for (uint64_t id : jobs_.FinishedJobs(std::nullopt)) {
      if (storeBytes_ <= *policy_.budgetBytes) break;
      Delete(id, reason);
    }
    if (storeBytes_ > *policy_.budgetBytes && !overBudgetLogged_) {
      overBudgetLogged_ = true;  // once, not every minute
      std::fprintf(stderr,
                   "coordinator: the store holds %s, more than its budget of %s (--store-budget), with no finished "
                   "job left to delete\n",
                   ShowBytes(storeBytes_).c_str(), ShowBytes(*policy_.budgetBytes).c_str());
    }
  }
}

void StoreJanitor::RunDue() {
  std::lock_guard<std::mutex> lock(dueMutex_);
  const int64_t now = nowMs_();
  const bool first = !lastMeasureMs_.has_value();
  try {
    if (first || now - *lastMeasureMs_ >= measureIntervalMs_) {
      lastMeasureMs_ = now;
      Measure();
    }
    if (first) FinishPendingDeletions();
    const int64_t orphanIntervalMs = std::min(kOrphanIntervalMs, policy_.orphanAssetGraceMs);
    if (!lastOrphanSweepMs_ || now - *lastOrphanSweepMs_ >= orphanIntervalMs) {
      lastOrphanSweepMs_ = now;
      RemoveOrphanAssets(now);
    }
    if (policy_.Active() && (!lastRetentionMs_ || now - *lastRetentionMs_ >= kRetentionIntervalMs)) {
      lastRetentionMs_ = now;
      ApplyRetention(now);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "coordinator: store upkeep failed, tried again later: %s\n", e.what());
  }
}

void StoreJanitor::Start() {
  std::lock_guard<std::mutex> lock(threadMutex_);
  if (thread_.joinable()) return;
  stopping_ = false;
  thread_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(threadMutex_);
    while (!stopping_) {
      lock.unlock();
      RunDue();
      lock.lock();
      wake_.wait_for(lock, std::chrono::seconds(1), [this] { return stopping_; });
    }
  });
}

void StoreJanitor::Stop() {
  {
    std::lock_guard<std::mutex> lock(threadMutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

}  // namespace tcfarm
