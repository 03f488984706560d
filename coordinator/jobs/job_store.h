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
//   failed, canceled ──Retry──> queued (frames kept)
//   completed, failed, canceled ──Delete──> gone (its id is never handed out again)
//
// completed, failed and canceled are final: only a user's Retry or Delete leaves them. A
// call that asks for any other transition (a late Complete after a Cancel, a RecordFrame
// after a Fail, ...) changes nothing and returns false: results that arrive late must
// never bring a finished job back to life.
//
// Every job keeps a log of events (submitted, started, frames_written, completed, ...),
// in the same file: each transition records its event in its own transaction, so the log
// and the record never disagree. Events carry a sequence number increasing across all
// jobs (JobEvent::seq), and listeners (AddEventListener) hear each one once committed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/jobs/untold_frames.h"
#include "coordinator/planner/strategy.h"

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
  // Whether any of its meshes deform (skins, morph targets): the kind of scene whose
  // measured prices auto's model borrows (PriceBook). Unknown for jobs stored before schema 5.
  std::optional<bool> deformingMeshes;
  // The assets (SHA-256) the submission named or its scene uses (textures): an asset is
  // deleted with the last job that names it (Delete).
  std::vector<std::string> assetHashes;
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

// What a list of jobs is filtered by; an empty member matches every job.
struct JobQuery {
  std::vector<JobState> states;        // any of these
  std::vector<Strategy> strategies;    // as submitted: kAuto matches the jobs submitted as auto
  std::string nameContains;            // a substring of the name, ASCII letters in either case
  int64_t limit = 0;                   // at most this many records; <= 0: all
  int64_t offset = 0;                  // skips this many matching jobs, newest first
};

struct JobPage {
  std::vector<JobRecord> records;  // newest (highest id) first, as List gives them
  uint64_t total = 0;              // every job matching the filters, whatever the page
};

// A frame recorded as written, with its pixels.
struct RecordedFrame {
  int frame = 0;  // the scene's frame number
  uint64_t traced = 0;
  uint64_t copied = 0;
};

// An event to record: its type (the API's names: "submitted", "frames_written", ...), a
// sentence for people, and the figures that go with it (a JSON object, or null for none).
struct EventDraft {
  std::string type;
  std::string message;
  nlohmann::json fields = nlohmann::json::object();
};

struct JobEvent {
  uint64_t seq = 0;  // across all jobs: increases with every event, never reused
  uint64_t job = 0;
  int64_t timeMs = 0;  // unix milliseconds
  std::string type;
  std::string message;
  nlohmann::json fields = nlohmann::json::object();
};

struct EventQuery {
  std::optional<uint64_t> job;  // none: every job's
  uint64_t afterSeq = 0;        // only events with a larger seq
  size_t limit = 1000;          // at most this many, ascending by seq
};

// What a job's priority and name become (PATCH); an empty member stays as it is.
struct JobChange {
  std::optional<int> priority;
  std::optional<std::string> name;
};

// What Delete did.
struct DeletedJob {
  enum class Outcome { kDeleted, kNotFound, kActive };
  Outcome outcome = Outcome::kNotFound;
  JobState state = JobState::kQueued;  // the job's state: the one it had when deleted, or that kept it
  // Assets the job named that no remaining job names: the caller removes their files.
  std::vector<std::string> unreferencedAssets;
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
  static constexpr int kSchemaVersion = 5;
  // frames_written events gather the frames recorded over this long, or this many frames,
  // whichever comes first: a 10,000-frame job writes a few hundred events, not 10,000,
  // and a watcher still hears of each frame within about a second.
  static constexpr int64_t kFrameEventIntervalMs = 1000;
  static constexpr size_t kFramesPerEvent = 10;

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
  // A page of the jobs that match, newest first, with how many match in all: one
  // consistent snapshot, counted and paged in SQL.
  JobPage Query(const JobQuery& query) const;
  size_t CountInState(JobState state) const;
  std::optional<JobState> StateOf(uint64_t id) const;
  // The job's frames recorded as written, ascending; empty for an unknown job.
  std::vector<RecordedFrame> RecordedFrames(uint64_t id) const;

  // The queued job with the highest priority, oldest first among equals, now running with
  // startedMs set. nullopt when nothing is queued. With `admit`, the first such job it
  // admits, of the first kClaimLooksAt in that order: it is given each one's record without
  // sceneJson and tracedPerFrame, inside the store's lock (it must not call the store);
  // nullopt when it admits none.
  static constexpr int kClaimLooksAt = 64;
  std::optional<JobRecord> ClaimNext(const std::function<bool(const JobRecord&)>& admit = {});

  // queued or running -> canceled (finishedMs set, partial counters kept). false when the
  // job is unknown or already final.
  bool Cancel(uint64_t id);

  // failed or canceled -> queued, under the same id: its recorded frames, counters,
  // startedMs, stats and plan stay (the next claim resumes it as after a restart), its
  // error and finishedMs are cleared. false when the job is unknown or in another state.
  bool Retry(uint64_t id);

  // Sets the job's priority and/or name, in any state; the ClaimNext order follows at once
  // (the farm is told separately about a running job). Records priority_changed and
  // renamed events for what really changed. false when the job is unknown. Throws
  // std::invalid_argument for a priority outside [kMinPriority, kMaxPriority].
  static constexpr int kMinPriority = -100;
  static constexpr int kMaxPriority = 100;
  bool Change(uint64_t id, const JobChange& change);

  // Removes a finished (completed, failed or canceled) job's record: its frames, scene,
  // events and asset names. The job's files are the caller's to remove: the job stays in
  // PendingDeletions until FinishDeletion, so that a crash in between leaves a note of the
  // folder to remove instead of an orphan. kActive (changing nothing) for a queued or
  // running job, kNotFound for an unknown one.
  DeletedJob Delete(uint64_t id);
  std::vector<uint64_t> PendingDeletions() const;
  // The job's files are gone: its note is dropped and `deleted` recorded as its last event
  // (the one event a deleted job keeps, for those who follow all events).
  void FinishDeletion(uint64_t id, const EventDraft& deleted);
  // Finished jobs, the earliest finished first (then the lowest id), at most `limit`
  // (0: all): those that finished before finishedBeforeMs when given. For retention.
  std::vector<uint64_t> FinishedJobs(std::optional<int64_t> finishedBeforeMs, size_t limit = 0) const;
  // Which of these assets (SHA-256) some job names: the store's janitor keeps those.
  std::set<std::string> NamedAssets(const std::vector<std::string>& hashes) const;

  // A frame of a running job finished. Counts each frame once: a duplicate result (a task
  // traced twice gives the same bits) is ignored. Ignored, returning false, when the job is
  // not running. Throws std::out_of_range when frame lies outside the job's range.
  bool RecordFrame(uint64_t id, int frame, uint64_t tracedPixels, uint64_t copiedPixels);

  // running -> completed (finishedMs set), stats merge-patched (RFC 7386) into the live
  // ones. false, changing nothing, in any other state: a canceled job stays canceled.
  // `before`: events recorded in the same transaction, ahead of the completed event (the
  // verification's figures).
  bool Complete(uint64_t id, const nlohmann::json& stats, const std::vector<EventDraft>& before = {});

  // queued or running -> failed with the reason (finishedMs set). false otherwise.
  bool Fail(uint64_t id, const std::string& error);

  // Merge-patches (RFC 7386) live stats into a running job's stats; false when not running.
  bool SetStats(uint64_t id, const nlohmann::json& stats);

  // For startup: jobs a previous coordinator process left running go back to queued. Their
  // recorded frames (written to the store before they were recorded), counters, startedMs,
  // stats and plan stay, so the next claim resumes them. Returns their ids, ascending.
  // Frames the previous process recorded but had not told yet (it died before a
  // frames_written event named them) are told first, in frames_written events marked
  // "recovered": true, so every recorded frame has its event.
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

  // The segment prices an exact job measured on a scene (PriceBook), kept for the next
  // coordinator: the last per scene, at most `keep` scenes, the longest unmeasured dropped.
  struct ScenePrices {
    std::string sceneHash;
    std::optional<bool> deforming;  // unknown for a job stored before schema 5
    double startPrice = 0, framePrice = 0;
  };
  void SaveScenePrices(const ScenePrices& prices, size_t keep);
  // Oldest measurement first, at most `limit` (the newest).
  std::vector<ScenePrices> LoadScenePrices(size_t limit) const;
  // Ids Submit hands out from now on are above `id` (a store's job folders up to it are
  // someone's already).
  void ReserveJobIdsThrough(uint64_t id);

  // Records an event of the job (one the transitions do not record themselves: a worker
  // lost, ...) and returns its seq.
  uint64_t AppendEvent(uint64_t id, const EventDraft& event);
  // Records the frames_written events owed for frames recorded over kFrameEventIntervalMs
  // ago. The farm calls it now and then; a job's transitions flush its own first.
  void FlushFrameEvents();
  std::vector<JobEvent> Events(const EventQuery& query) const;
  uint64_t LastEventSeq() const;  // 0 before any event

  // Called with each event once its transaction is committed, on the thread that recorded
  // it, while the store is locked: a listener must not call the store. Returns an id for
  // RemoveEventListener, after which the listener is never called again.
  using EventListener = std::function<void(const JobEvent&)>;
  uint64_t AddEventListener(EventListener listener);
  void RemoveEventListener(uint64_t listenerId);

  // Caps the file at `pages` pages (SQLite's PRAGMA max_page_count, this connection only):
  // writes beyond it fail with JobStoreFullError as on a full disk. For tests.
  void CapFilePages(int64_t pages);

 private:
  // Inside a write transaction: records the event, to be announced once committed.
  void Record(uint64_t id, const EventDraft& event, std::vector<JobEvent>& recorded);
  // Inside a write transaction: the frames_written event of the job's untold frames (and
  // forgets them once committed, through `told`).
  void RecordUntoldFrames(uint64_t id, std::vector<JobEvent>& recorded, std::vector<uint64_t>& told);
  // Inside a write transaction: frames_written events (marked recovered) for the job's
  // recorded frames that no event names, as a crash leaves them.
  void RecordUntoldFramesOfCrash(uint64_t id, std::vector<JobEvent>& recorded);
  // After the commit.
  void Announce(const std::vector<JobEvent>& recorded, const std::vector<uint64_t>& told);

  mutable std::mutex mutex_;  // serializes all use of the single connection
  std::unique_ptr<sqlite::Database> db_;
  ClockMs nowMs_;
  jobs::UntoldFrames untold_;
  std::map<uint64_t, EventListener> listeners_;
  uint64_t nextListenerId_ = 1;
};

}  // namespace tcfarm
