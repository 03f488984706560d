#include "coordinator/jobs/job_store.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "coordinator/jobs/job_event_log.h"
#include "coordinator/jobs/job_rows.h"
#include "coordinator/jobs/job_schema.h"
#include "coordinator/jobs/sqlite_database.h"

namespace tcfarm {

namespace {

constexpr std::array<std::pair<JobState, const char*>, 5> kStateNames = {{
    {JobState::kQueued, "queued"},
    {JobState::kRunning, "running"},
    {JobState::kCompleted, "completed"},
    {JobState::kFailed, "failed"},
    {JobState::kCanceled, "canceled"},
}};

}  // namespace

std::string ToString(JobState state) {
  for (const auto& [value, name] : kStateNames) {
    if (value == state) return name;
  }
  return "unknown";
}

std::optional<JobState> JobStateFromString(std::string_view name) {
  for (const auto& [value, stateName] : kStateNames) {
    if (name == stateName) return value;
  }
  return std::nullopt;
}

double JobRecord::TracedPixelRatio(uint64_t pixelsPerFrame) const {
  const double bruteForcePixels = static_cast<double>(pixelsPerFrame) * framesDone;
  if (bruteForcePixels <= 0) return 0;
  return static_cast<double>(tracedPixels) / bruteForcePixels;
}

namespace {

using jobs::BindJobFilter;
using jobs::ConfigureConnection;
using jobs::FramesWrittenEvent;
using jobs::InsertAssetNames;
using jobs::kJobFilter;
using jobs::kSelectJobColumns;
using jobs::LoadFullRecord;
using jobs::LoadRecordRow;
using jobs::MergeStats;
using jobs::MigrateForward;
using jobs::ReadRecord;
using jobs::ReadState;
using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

void ValidateSpec(const JobSpec& spec) {
  if (spec.lastFrame < spec.firstFrame) {
    throw std::invalid_argument("job spec: lastFrame " + std::to_string(spec.lastFrame) +
                                " is before firstFrame " + std::to_string(spec.firstFrame));
  }
  if (spec.binWidth < 1) {
    throw std::invalid_argument("job spec: binWidth must be at least 1, got " +
                                std::to_string(spec.binWidth));
  }
  if (!std::isfinite(spec.tolerance) || spec.tolerance < 0) {
    throw std::invalid_argument("job spec: tolerance must be finite and >= 0, got " +
                                std::to_string(spec.tolerance));
  }
  if (spec.priority < JobStore::kMinPriority || spec.priority > JobStore::kMaxPriority) {
    throw std::invalid_argument("job spec: priority must be in [" + std::to_string(JobStore::kMinPriority) + ", " +
                                std::to_string(JobStore::kMaxPriority) + "], got " + std::to_string(spec.priority));
  }
  if (spec.frameSize.width < 1 || spec.frameSize.height < 1) {
    throw std::invalid_argument("job spec: frameSize must be at least 1x1, got " +
                                std::to_string(spec.frameSize.width) + "x" +
                                std::to_string(spec.frameSize.height));
  }
}

// One guarded UPDATE moves a job between states: the WHERE clause names the states the
// transition may leave, so a job in any other state is left alone and no row changes.
bool Transition(Database& db, uint64_t id, const char* guardedUpdate, int64_t nowMs) {
  Statement statement(db, guardedUpdate);
  statement.Bind(1, static_cast<int64_t>(id)).Bind(2, nowMs);
  statement.Run();
  return db.Changes() == 1;
}

std::string FramesOf(const JobRecord& record) {
  return std::to_string(record.framesDone) + " of " + std::to_string(record.FrameCount()) + " frames";
}

// "0.231", "12.4": figures for messages, without trailing noise.
std::string Figure(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// JobStore

int64_t JobStore::SystemNowMs() {
  using namespace std::chrono;
  return duration_cast<milliseconds>(system_clock::now().time_since_epoch()).count();
}

JobStore::JobStore(const std::filesystem::path& file, ClockMs nowMs)
    : db_(std::make_unique<sqlite::Database>(file)), nowMs_(std::move(nowMs)) {
  ConfigureConnection(*db_);
  MigrateForward(*db_);
}

JobStore::~JobStore() = default;

uint64_t JobStore::Submit(const JobSpec& spec) {
  ValidateSpec(spec);
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement insert(*db_,
                   "INSERT INTO jobs (name, scene_hash, first_frame, last_frame, strategy, "
                   "bin_width, tolerance, priority, options, state, submitted_ms, width, height, "
                   "camera_or_lights_change, deforming_meshes) "
                   "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, 'queued', ?10, ?11, ?12, ?13, ?14)");
  insert.Bind(1, spec.name).Bind(2, spec.sceneHash);
  insert.Bind(3, int64_t{spec.firstFrame}).Bind(4, int64_t{spec.lastFrame});
  insert.Bind(5, StrategyName(spec.strategy)).Bind(6, int64_t{spec.binWidth}).Bind(7, spec.tolerance);
  insert.Bind(8, int64_t{spec.priority}).Bind(9, spec.options.dump()).Bind(10, nowMs_());
  insert.Bind(11, int64_t{spec.frameSize.width}).Bind(12, int64_t{spec.frameSize.height});
  if (spec.cameraOrLightsChange) insert.Bind(13, int64_t{*spec.cameraOrLightsChange ? 1 : 0});
  if (spec.deformingMeshes) insert.Bind(14, int64_t{*spec.deformingMeshes ? 1 : 0});
  insert.Run();
  const int64_t id = db_->LastInsertRowId();
  Statement scene(*db_, "INSERT INTO job_scenes (job_id, scene_json) VALUES (?1, ?2)");
  scene.Bind(1, id).Bind(2, spec.sceneJson);
  scene.Run();
  InsertAssetNames(*db_, id, spec.assetHashes);
  std::vector<JobEvent> recorded;
  const std::string name = spec.name.empty() ? "" : " '" + spec.name + "'";
  Record(static_cast<uint64_t>(id),
         {"submitted",
          "submitted" + name + ": " + std::string(StrategyName(spec.strategy)) + ", frames " + std::to_string(spec.firstFrame) +
              ".." + std::to_string(spec.lastFrame) + ", priority " + std::to_string(spec.priority),
          {{"name", spec.name},
           {"strategy", std::string(StrategyName(spec.strategy))},
           {"frames", {{"start", spec.firstFrame}, {"end", spec.lastFrame}}},
           {"priority", spec.priority}}},
         recorded);
  transaction.Commit();
  Announce(recorded, {});
  return static_cast<uint64_t>(id);
}

std::optional<JobRecord> JobStore::Get(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  // The row, scene and frames as one snapshot, even while another process writes.
  Transaction snapshot(*db_, Transaction::Mode::kRead);
  std::optional<JobRecord> record = LoadFullRecord(*db_, id);
  snapshot.Commit();
  return record;
}

std::vector<JobRecord> JobStore::List(std::optional<JobState> state, int limit) const {
  JobQuery query;
  if (state) query.states = {*state};
  query.limit = limit;
  return Query(query).records;
}

JobPage JobStore::Query(const JobQuery& query) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction snapshot(*db_, Transaction::Mode::kRead);
  JobPage page;
  // SQLite reads a negative LIMIT as no limit.
  Statement select(*db_, kSelectJobColumns + kJobFilter + "ORDER BY id DESC LIMIT ?4 OFFSET ?5");
  BindJobFilter(select, query);
  select.Bind(4, query.limit > 0 ? query.limit : int64_t{-1}).Bind(5, std::max<int64_t>(0, query.offset));
  while (select.Step()) page.records.push_back(ReadRecord(select));
  Statement count(*db_, "SELECT COUNT(*) FROM jobs " + kJobFilter);
  BindJobFilter(count, query);
  count.Step();
  page.total = count.UInt64(0);
  snapshot.Commit();
  return page;
}

size_t JobStore::CountInState(JobState state) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT COUNT(*) FROM jobs WHERE state = ?1");
  statement.Bind(1, ToString(state));
  statement.Step();
  return static_cast<size_t>(statement.Int64(0));
}

std::optional<JobState> JobStore::StateOf(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ReadState(*db_, id);
}

std::vector<RecordedFrame> JobStore::RecordedFrames(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT frame, traced, copied FROM job_frames WHERE job_id = ?1 ORDER BY frame");
  statement.Bind(1, static_cast<int64_t>(id));
  std::vector<RecordedFrame> frames;
  while (statement.Step()) frames.push_back({statement.Int(0), statement.UInt64(1), statement.UInt64(2)});
  return frames;
}

std::optional<JobRecord> JobStore::ClaimNext(const std::function<bool(const JobRecord&)>& admit) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  std::optional<uint64_t> admitted;
  {
    Statement next(*db_, kSelectJobColumns + "WHERE state = 'queued' ORDER BY priority DESC, id LIMIT ?1");
    next.Bind(1, int64_t{admit ? kClaimLooksAt : 1});
    while (!admitted && next.Step()) {
      const JobRecord candidate = ReadRecord(next);
      if (!admit || admit(candidate)) admitted = candidate.id;
    }
  }
  if (!admitted) return std::nullopt;
  const uint64_t id = *admitted;
  Transition(*db_, id,
             // A resumed job keeps the time it first started.
             "UPDATE jobs SET state = 'running', "
             "started_ms = CASE WHEN started_ms = 0 THEN ?2 ELSE started_ms END "
             "WHERE id = ?1 AND state = 'queued'",
             nowMs_());
  std::optional<JobRecord> record = LoadFullRecord(*db_, id);
  std::vector<JobEvent> recorded;
  Record(id,
         {"started",
          record->framesDone > 0 ? "resumed with " + FramesOf(*record) + " already written" : "started",
          {{"frames_written", record->framesDone}}},
         recorded);
  transaction.Commit();
  Announce(recorded, {});
  return record;
}

bool JobStore::Cancel(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  if (!Transition(*db_, id,
                  "UPDATE jobs SET state = 'canceled', finished_ms = ?2 "
                  "WHERE id = ?1 AND state IN ('queued', 'running')",
                  nowMs_())) {
    return false;
  }
  std::vector<JobEvent> recorded;
  std::vector<uint64_t> told;
  RecordUntoldFrames(id, recorded, told);
  const JobRecord record = *LoadRecordRow(*db_, id);
  Record(id, {"canceled", "canceled with " + FramesOf(record) + " written", {{"frames_written", record.framesDone}}},
         recorded);
  transaction.Commit();
  Announce(recorded, told);
  return true;
}

bool JobStore::Retry(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  const std::optional<JobState> before = ReadState(*db_, id);
  Statement requeue(*db_, "UPDATE jobs SET state = 'queued', finished_ms = 0, error = '' "
                          "WHERE id = ?1 AND state IN ('failed', 'canceled')");
  requeue.Bind(1, static_cast<int64_t>(id));
  requeue.Run();
  if (db_->Changes() != 1) return false;
  const JobRecord record = *LoadRecordRow(*db_, id);
  std::vector<JobEvent> recorded;
  Record(id,
         {"retried",
          "queued again after it " + std::string(before == JobState::kFailed ? "failed" : "was canceled") + "; " +
              FramesOf(record) + " written are kept",
          {{"previous_state", ToString(before.value_or(JobState::kFailed))}, {"frames_kept", record.framesDone}}},
         recorded);
  transaction.Commit();
  Announce(recorded, {});
  return true;
}

bool JobStore::Change(uint64_t id, const JobChange& change) {
  if (change.priority && (*change.priority < kMinPriority || *change.priority > kMaxPriority)) {
    throw std::invalid_argument("job " + std::to_string(id) + ": priority " + std::to_string(*change.priority) +
                                " is outside [" + std::to_string(kMinPriority) + ", " +
                                std::to_string(kMaxPriority) + "]");
  }
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  const std::optional<JobRecord> record = LoadRecordRow(*db_, id);
  if (!record) return false;
  std::vector<JobEvent> recorded;
  if (change.priority && *change.priority != record->spec.priority) {
    Statement update(*db_, "UPDATE jobs SET priority = ?2 WHERE id = ?1");
    update.Bind(1, static_cast<int64_t>(id)).Bind(2, int64_t{*change.priority});
    update.Run();
    Record(id,
           {"priority_changed",
            "priority changed from " + std::to_string(record->spec.priority) + " to " +
                std::to_string(*change.priority),
            {{"from", record->spec.priority}, {"to", *change.priority}}},
           recorded);
  }
  if (change.name && *change.name != record->spec.name) {
    Statement update(*db_, "UPDATE jobs SET name = ?2 WHERE id = ?1");
    update.Bind(1, static_cast<int64_t>(id)).Bind(2, *change.name);
    update.Run();
    Record(id,
           {"renamed", "renamed from '" + record->spec.name + "' to '" + *change.name + "'",
            {{"from", record->spec.name}, {"to", *change.name}}},
           recorded);
  }
  transaction.Commit();
  Announce(recorded, {});
  return true;
}

DeletedJob JobStore::Delete(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  DeletedJob deleted;
  const std::optional<JobState> state = ReadState(*db_, id);
  if (!state) return deleted;
  deleted.state = *state;
  if (*state == JobState::kQueued || *state == JobState::kRunning) {
    deleted.outcome = DeletedJob::Outcome::kActive;
    return deleted;
  }
  Statement unshared(*db_,
                     "SELECT sha256 FROM job_assets AS mine WHERE job_id = ?1 AND NOT EXISTS "
                     "(SELECT 1 FROM job_assets AS other WHERE other.sha256 = mine.sha256 AND other.job_id != ?1) "
                     "ORDER BY sha256");
  unshared.Bind(1, static_cast<int64_t>(id));
  while (unshared.Step()) deleted.unreferencedAssets.push_back(unshared.Text(0));
  Statement note(*db_, "INSERT OR IGNORE INTO job_deletions (job_id) VALUES (?1)");
  note.Bind(1, static_cast<int64_t>(id));
  note.Run();
  Statement events(*db_, "DELETE FROM job_events WHERE job_id = ?1");
  events.Bind(1, static_cast<int64_t>(id));
  events.Run();
  // Its frames, scene and asset names go with it (ON DELETE CASCADE).
  Statement job(*db_, "DELETE FROM jobs WHERE id = ?1");
  job.Bind(1, static_cast<int64_t>(id));
  job.Run();
  transaction.Commit();
  untold_.Clear(id);
  deleted.outcome = DeletedJob::Outcome::kDeleted;
  return deleted;
}

std::vector<uint64_t> JobStore::PendingDeletions() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT job_id FROM job_deletions ORDER BY job_id");
  std::vector<uint64_t> ids;
  while (statement.Step()) ids.push_back(statement.UInt64(0));
  return ids;
}

void JobStore::FinishDeletion(uint64_t id, const EventDraft& deleted) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement statement(*db_, "DELETE FROM job_deletions WHERE job_id = ?1");
  statement.Bind(1, static_cast<int64_t>(id));
  statement.Run();
  std::vector<JobEvent> recorded;
  if (db_->Changes() == 1) Record(id, deleted, recorded);
  transaction.Commit();
  Announce(recorded, {});
}

std::vector<uint64_t> JobStore::FinishedJobs(std::optional<int64_t> finishedBeforeMs, size_t limit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_,
                      "SELECT id FROM jobs WHERE state IN ('completed', 'failed', 'canceled') "
                      "AND (?1 IS NULL OR finished_ms < ?1) ORDER BY finished_ms, id LIMIT ?2");
  if (finishedBeforeMs) statement.Bind(1, *finishedBeforeMs);
  statement.Bind(2, limit > 0 ? static_cast<int64_t>(limit) : int64_t{-1});
  std::vector<uint64_t> ids;
  while (statement.Step()) ids.push_back(statement.UInt64(0));
  return ids;
}

std::set<std::string> JobStore::NamedAssets(const std::vector<std::string>& hashes) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT 1 FROM job_assets WHERE sha256 = ?1 LIMIT 1");
  std::set<std::string> named;
  for (const std::string& hash : hashes) {
    statement.Reset();
    statement.Bind(1, hash);
    if (statement.Step()) named.insert(hash);
  }
  return named;
}

bool JobStore::RecordFrame(uint64_t id, int frame, uint64_t tracedPixels,
                           uint64_t copiedPixels) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  std::optional<JobRecord> record = LoadRecordRow(*db_, id);
  if (!record || record->state != JobState::kRunning) return false;
  if (frame < record->spec.firstFrame || frame > record->spec.lastFrame) {
    throw std::out_of_range("job " + std::to_string(id) + ": frame " + std::to_string(frame) +
                            " outside [" + std::to_string(record->spec.firstFrame) + ", " +
                            std::to_string(record->spec.lastFrame) + "]");
  }
  Statement insert(*db_, "INSERT OR IGNORE INTO job_frames (job_id, frame, traced, copied) "
                         "VALUES (?1, ?2, ?3, ?4)");
  insert.Bind(1, static_cast<int64_t>(id)).Bind(2, int64_t{frame});
  insert.Bind(3, static_cast<int64_t>(tracedPixels)).Bind(4, static_cast<int64_t>(copiedPixels));
  insert.Run();
  if (db_->Changes() == 0) return false;  // this frame was already counted
  Statement update(*db_, "UPDATE jobs SET frames_done = frames_done + 1, "
                         "traced_pixels = traced_pixels + ?2, copied_pixels = copied_pixels + ?3 "
                         "WHERE id = ?1");
  update.Bind(1, static_cast<int64_t>(id)).Bind(2, static_cast<int64_t>(tracedPixels));
  update.Bind(3, static_cast<int64_t>(copiedPixels));
  update.Run();
  // The frame joins the job's untold ones; enough of them are told at once, in this
  // transaction, the others by a later call (or FlushFrameEvents).
  const int64_t now = nowMs_();
  std::vector<int> frames = untold_.Of(id);
  frames.push_back(frame);
  std::vector<JobEvent> recorded;
  if (frames.size() >= kFramesPerEvent) Record(id, FramesWrittenEvent(frames), recorded);
  transaction.Commit();
  if (!recorded.empty()) {
    Announce(recorded, {id});
  } else {
    untold_.Add(id, frame, now);
  }
  return true;
}

bool JobStore::Complete(uint64_t id, const nlohmann::json& stats, const std::vector<EventDraft>& before) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  const int64_t now = nowMs_();
  const bool completed = Transition(*db_, id,
                                    "UPDATE jobs SET state = 'completed', finished_ms = ?2 "
                                    "WHERE id = ?1 AND state = 'running'",
                                    now);
  if (!completed) return false;
  MergeStats(*db_, id, stats);
  std::vector<JobEvent> recorded;
  std::vector<uint64_t> told;
  RecordUntoldFrames(id, recorded, told);
  for (const EventDraft& event : before) Record(id, event, recorded);
  const JobRecord record = *LoadRecordRow(*db_, id);
  const double ratio = record.TracedPixelRatio(record.spec.frameSize.Pixels());
  // This run's wall time as the farm measured it; the record's since the first start
  // for a job completed without figures.
  const nlohmann::json measured = stats.is_object() ? stats.value("wall_seconds", nlohmann::json()) : nlohmann::json();
  const double wall = measured.is_number() ? measured.get<double>() : (now - record.startedMs) / 1000.0;
  Record(id,
         {"completed",
          "completed: " + std::to_string(record.framesDone) + " frames, traced-pixel ratio " + Figure(ratio, 3) +
              ", " + Figure(wall, 1) + " s",
          {{"traced_pixel_ratio", ratio}, {"wall_seconds", wall}, {"frames_written", record.framesDone}}},
         recorded);
  transaction.Commit();
  Announce(recorded, told);
  return true;
}

bool JobStore::Fail(uint64_t id, const std::string& error) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement statement(*db_, "UPDATE jobs SET state = 'failed', finished_ms = ?2, error = ?3 "
                            "WHERE id = ?1 AND state IN ('queued', 'running')");
  statement.Bind(1, static_cast<int64_t>(id)).Bind(2, nowMs_()).Bind(3, error);
  statement.Run();
  if (db_->Changes() != 1) return false;
  std::vector<JobEvent> recorded;
  std::vector<uint64_t> told;
  RecordUntoldFrames(id, recorded, told);
  const JobRecord record = *LoadRecordRow(*db_, id);
  Record(id, {"failed", "failed: " + error, {{"reason", error}, {"frames_written", record.framesDone}}}, recorded);
  transaction.Commit();
  Announce(recorded, told);
  return true;
}

bool JobStore::SetStats(uint64_t id, const nlohmann::json& stats) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  if (ReadState(*db_, id) != JobState::kRunning) return false;
  MergeStats(*db_, id, stats);
  transaction.Commit();
  return true;
}

std::vector<uint64_t> JobStore::RequeueInterrupted() {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  std::vector<uint64_t> ids;
  Statement running(*db_, "SELECT id FROM jobs WHERE state = 'running' ORDER BY id");
  while (running.Step()) ids.push_back(running.UInt64(0));
  db_->Exec("UPDATE jobs SET state = 'queued' WHERE state = 'running'");
  std::vector<JobEvent> recorded;
  for (uint64_t id : ids) {
    RecordUntoldFramesOfCrash(id, recorded);
    const JobRecord record = *LoadRecordRow(*db_, id);
    Record(id,
           {"requeued",
            "the coordinator stopped while it ran; queued again to resume with " + FramesOf(record) + " written",
            {{"frames_written", record.framesDone}}},
           recorded);
  }
  transaction.Commit();
  Announce(recorded, {});
  return ids;
}

bool JobStore::SetPlan(uint64_t id, const nlohmann::json& plan) {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "UPDATE jobs SET plan = ?2 WHERE id = ?1 AND state = 'running'");
  statement.Bind(1, static_cast<int64_t>(id)).Bind(2, plan.dump());
  statement.Run();
  return db_->Changes() == 1;
}

void JobStore::ForgetFrames(uint64_t id, const std::vector<int>& frames) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement read(*db_, "SELECT traced, copied FROM job_frames WHERE job_id = ?1 AND frame = ?2");
  Statement remove(*db_, "DELETE FROM job_frames WHERE job_id = ?1 AND frame = ?2");
  Statement update(*db_, "UPDATE jobs SET frames_done = frames_done - 1, traced_pixels = traced_pixels - ?2, "
                         "copied_pixels = copied_pixels - ?3 WHERE id = ?1");
  for (int frame : frames) {
    read.Reset();
    read.Bind(1, static_cast<int64_t>(id)).Bind(2, int64_t{frame});
    if (!read.Step()) continue;
    const int64_t traced = read.Int64(0), copied = read.Int64(1);
    read.Reset();
    remove.Reset();
    remove.Bind(1, static_cast<int64_t>(id)).Bind(2, int64_t{frame});
    remove.Run();
    update.Reset();
    update.Bind(1, static_cast<int64_t>(id)).Bind(2, traced).Bind(3, copied);
    update.Run();
  }
  transaction.Commit();
  untold_.Forget(id, frames);
}

std::optional<std::string> JobStore::StoreId() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT store_id FROM store_identity");
  if (!statement.Step()) return std::nullopt;
  return statement.Text(0);
}

void JobStore::SetStoreId(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "INSERT OR REPLACE INTO store_identity (one_row, store_id) VALUES (1, ?1)");
  statement.Bind(1, id);
  statement.Run();
}

void JobStore::SaveScenePrices(const ScenePrices& prices, size_t keep) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement upsert(*db_,
                   "INSERT OR REPLACE INTO scene_prices (scene_hash, deforming, start_price, frame_price, "
                   "measured_ms) VALUES (?1, ?2, ?3, ?4, ?5)");
  upsert.Bind(1, prices.sceneHash);
  if (prices.deforming) upsert.Bind(2, int64_t{*prices.deforming ? 1 : 0});
  upsert.Bind(3, prices.startPrice).Bind(4, prices.framePrice).Bind(5, nowMs_());
  upsert.Run();
  Statement trim(*db_,
                 "DELETE FROM scene_prices WHERE scene_hash NOT IN "
                 "(SELECT scene_hash FROM scene_prices ORDER BY measured_ms DESC, rowid DESC LIMIT ?1)");
  trim.Bind(1, static_cast<int64_t>(keep));
  trim.Run();
  transaction.Commit();
}

std::vector<JobStore::ScenePrices> JobStore::LoadScenePrices(size_t limit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement select(*db_,
                   "SELECT scene_hash, deforming, start_price, frame_price FROM "
                   "(SELECT *, rowid AS r FROM scene_prices ORDER BY measured_ms DESC, r DESC LIMIT ?1) "
                   "ORDER BY measured_ms, r");
  select.Bind(1, static_cast<int64_t>(limit));
  std::vector<ScenePrices> rows;
  while (select.Step()) {
    ScenePrices row{select.Text(0), std::nullopt, select.Double(2), select.Double(3)};
    if (!select.IsNull(1)) row.deforming = select.Int(1) != 0;
    rows.push_back(std::move(row));
  }
  return rows;
}

bool JobStore::HasJob(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT 1 FROM jobs WHERE id = ?1");
  statement.Bind(1, static_cast<int64_t>(id));
  return statement.Step();
}

size_t JobStore::JobCount() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT COUNT(*) FROM jobs");
  statement.Step();
  return static_cast<size_t>(statement.Int64(0));
}

void JobStore::CapFilePages(int64_t pages) {
  std::lock_guard<std::mutex> lock(mutex_);
  // PRAGMA takes no bound parameters; pages is an integer, never text.
  db_->Exec(("PRAGMA max_page_count = " + std::to_string(pages)).c_str());
}

// AUTOINCREMENT hands out max(largest id ever used, sqlite_sequence's value) + 1; the
// sequence's row exists once a job was ever inserted.
void JobStore::ReserveJobIdsThrough(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  Statement update(*db_, "UPDATE sqlite_sequence SET seq = MAX(seq, ?1) WHERE name = 'jobs'");
  update.Bind(1, static_cast<int64_t>(id));
  update.Run();
  if (db_->Changes() == 0) {
    Statement insert(*db_, "INSERT INTO sqlite_sequence (name, seq) VALUES ('jobs', ?1)");
    insert.Bind(1, static_cast<int64_t>(id));
    insert.Run();
  }
  transaction.Commit();
}

}  // namespace tcfarm
