// The job queue: every render job the coordinator has accepted, kept in one SQLite file.
//
// The file outlives the coordinator process, so a restart loses no submitted job: jobs
// it was running go back to the queue with the frames they had written (RequeueInterrupted),
// everything else is as it was. It also records which frame store it belongs to (StoreId).
//
// A job moves through these states, and no other transition is possible:
//
//   Submit ──> queued ──ClaimNext──> running ──Complete──> completed
//                 │                     │
//                 │                     ├──Fail──> failed
//                 ├──Fail──> failed     ├──Cancel──> canceled
//                 └──Cancel──> canceled └──RequeueInterrupted──> queued (frames kept)
//
// completed, failed and canceled are final. A call that asks for any other transition
// (a late Complete after a Cancel, a RecordFrame after a Fail, ...) changes nothing and
// returns false: results that arrive late must never bring a finished job back to life.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "planner/strategy.h"

namespace tcfarm {

enum class JobState { kQueued, kRunning, kCompleted, kFailed, kCanceled };

// "queued", "running", "completed", "failed", "canceled": the names the HTTP API and the
// database use.
std::string ToString(JobState state);
std::optional<JobState> JobStateFromString(std::string_view name);

// A frame's size in pixels.
struct FrameSize {
  int width = 0;
  int height = 0;
  uint64_t Pixels() const { return static_cast<uint64_t>(width) * static_cast<uint64_t>(height); }
};

struct JobSpec {
  std::string name;       // the user's label, may be empty
  std::string sceneJson;  // self-contained scene JSON, already validated by the caller
  std::string sceneHash;  // SHA-256 hex of sceneJson, computed by the caller
  int firstFrame = 0;     // inclusive
  int lastFrame = 0;      // inclusive
  Strategy strategy = kDefaultStrategy;  // as requested: kAuto stays kAuto here
  int binWidth = 10;                // frames per bin
  double tolerance = 0;
  int priority = 0;        // higher runs first and gets a larger share of the workers
  nlohmann::json options;  // anything else (verify settings, ...), stored as JSON text
  // Taken from the scene when it is parsed at submit, so that nothing parses it again: its
  // render size (>= 1 x 1), and whether its camera or a light changes (auto's rule).
  // Jobs stored before schema 2 get their size when the file is migrated; whether their
  // camera or lights change is not known (nullopt).
  FrameSize frameSize;
  std::optional<bool> cameraOrLightsChange;
};

struct JobRecord {
  uint64_t id = 0;
  JobSpec spec;  // spec.sceneJson is empty in List results; Get loads it
  JobState state = JobState::kQueued;
  std::string error;  // why it failed, when it failed
  int64_t submittedMs = 0;  // unix milliseconds; 0 when not yet
  int64_t startedMs = 0;
  int64_t finishedMs = 0;
  int framesDone = 0;  // frames recorded as finished
  uint64_t tracedPixels = 0;
  uint64_t copiedPixels = 0;
  // Traced pixels per frame, index = frame - firstFrame, -1 for frames not finished yet.
  // Get fills it (FrameCount() entries); List leaves it empty so that listing stays cheap
  // whatever the jobs' lengths.
  std::vector<int64_t> tracedPerFrame;
  nlohmann::json stats = nlohmann::json::object();  // results the coordinator attaches
  // How the job runs, fixed when it first starts (SetPlan): the resolved strategy and bin
  // width, so that a coordinator resuming it plans the same bins whatever its worker
  // count. Empty until then.
  nlohmann::json plan = nlohmann::json::object();

  int FrameCount() const { return spec.lastFrame - spec.firstFrame + 1; }
  // Traced pixels over the pixels a brute-force render of the finished frames would have
  // traced: 1 is no saving, 0.1 traced a tenth. 0 when no frame is finished yet.
  double TracedPixelRatio(uint64_t pixelsPerFrame) const;
};

// Any failure of the database itself: the message names the file and SQLite's reason.
class JobStoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A write the disk refused (SQLITE_FULL, or an I/O error: the disk is full or failing).
// Nothing of the refused call is kept; reads go on working, and the same call succeeds
// once there is room again.
class JobStoreFullError : public JobStoreError {
 public:
  using JobStoreError::JobStoreError;
};

namespace sqlite {
class Database;
}

// Thread-safe: one connection behind one mutex. Several JobStores (or processes) may open
// the same file; every read-modify-write is one IMMEDIATE transaction, so a job is still
// claimed at most once.
class JobStore {
 public:
  using ClockMs = std::function<int64_t()>;  // unix milliseconds
  static int64_t SystemNowMs();

  // The newest schema this code knows. A file with a newer one is refused, since an older
  // coordinator cannot know what the newer columns mean.
  static constexpr int kSchemaVersion = 3;

  // Creates the file or opens it, migrating an older schema forward. Throws JobStoreError
  // naming the path when the file is not a database, is unreadable, or is too new.
  explicit JobStore(const std::filesystem::path& file, ClockMs nowMs = SystemNowMs);
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  // Adds a queued job and returns its id (ids only grow, never reused). Throws
  // std::invalid_argument when the frame range is empty, binWidth < 1, tolerance is
  // negative or not finite, or the frame size is not at least 1 x 1.
  uint64_t Submit(const JobSpec& spec);

  std::optional<JobRecord> Get(uint64_t id) const;  // with sceneJson and tracedPerFrame
  // Newest first, at most limit records (limit <= 0: all), without sceneJson and
  // tracedPerFrame.
  std::vector<JobRecord> List(std::optional<JobState> state = std::nullopt, int limit = 100) const;
  size_t CountInState(JobState state) const;

  // The queued job with the highest priority, oldest first among equals, now running with
  // startedMs set. nullopt when nothing is queued.
  std::optional<JobRecord> ClaimNext();

  // queued or running -> canceled (finishedMs set, partial counters kept). false when the
  // job is unknown or already final.
  bool Cancel(uint64_t id);

  // A frame of a running job finished. Counts each frame once: a duplicate result (a task
  // traced twice gives the same bits) is ignored. Ignored, returning false, when the job is
  // not running. Throws std::out_of_range when frame lies outside the job's range.
  bool RecordFrame(uint64_t id, int frame, uint64_t tracedPixels, uint64_t copiedPixels);

  // running -> completed (finishedMs set), stats merge-patched (RFC 7386) into the live
  // ones. false, changing nothing, in any other state: a canceled job stays canceled.
  bool Complete(uint64_t id, const nlohmann::json& stats);

  // queued or running -> failed with the reason (finishedMs set). false otherwise.
  bool Fail(uint64_t id, const std::string& error);

  // Merge-patches (RFC 7386) live stats into a running job's stats; false when not running.
  bool SetStats(uint64_t id, const nlohmann::json& stats);

  // For startup: jobs a previous coordinator process left running go back to queued. Their
  // recorded frames (written to the store before they were recorded), counters, startedMs,
  // stats and plan stay, so the next claim resumes them. Returns their ids, ascending.
  std::vector<uint64_t> RequeueInterrupted();

  // Fixes a running job's plan (JobRecord::plan); false when the job is not running.
  bool SetPlan(uint64_t id, const nlohmann::json& plan);
  // Un-records frames whose files are gone from the store, their counters with them, so
  // the record says what the store holds. Frames not recorded are skipped.
  void ForgetFrames(uint64_t id, const std::vector<int>& frames);

  // The frame store this database belongs to (its identity file's id); nullopt before
  // one is recorded.
  std::optional<std::string> StoreId() const;
  void SetStoreId(const std::string& id);
  bool HasJob(uint64_t id) const;
  size_t JobCount() const;
  // Ids Submit hands out from now on are above `id` (a store's job folders up to it are
  // someone's already).
  void ReserveJobIdsThrough(uint64_t id);

  // Caps the file at `pages` pages (SQLite's PRAGMA max_page_count, this connection only):
  // writes beyond it fail with JobStoreFullError as on a full disk. For tests.
  void CapFilePages(int64_t pages);

 private:
  mutable std::mutex mutex_;  // serializes all use of the single connection
  std::unique_ptr<sqlite::Database> db_;
  ClockMs nowMs_;
};

}  // namespace tcfarm
