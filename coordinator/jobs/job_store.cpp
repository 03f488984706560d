#include "jobs/job_store.h"

#include <sqlite3.h>

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

namespace tcfarm {

namespace {

constexpr std::array<std::pair<JobState, const char*>, 5> kStateNames = {{
    {JobState::kQueued, "queued"},
    {JobState::kRunning, "running"},
    {JobState::kCompleted, "completed"},
    {JobState::kFailed, "failed"},
    {JobState::kCanceled, "canceled"},
}};

// Long enough to ride out another connection's commit (another process on the same file),
// short enough that a wedged lock surfaces as an error instead of a hung coordinator.
constexpr int kBusyTimeoutMs = 5000;

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

// ---------------------------------------------------------------------------------------
// Thin RAII wrappers over the SQLite C API. Every value reaches SQL through a bound
// parameter; SQL text is always a literal.

namespace sqlite {

class Database {
 public:
  explicit Database(const std::filesystem::path& file) : path_(file.string()) {
    const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    const int rc = sqlite3_open_v2(path_.c_str(), &handle_, flags, nullptr);
    if (rc != SQLITE_OK) {
      // sqlite3_open_v2 allocates a handle even on failure, to carry the message.
      const std::string reason = handle_ ? sqlite3_errmsg(handle_) : sqlite3_errstr(rc);
      sqlite3_close(handle_);
      handle_ = nullptr;
      throw JobStoreError(path_ + ": cannot open job database: " + reason);
    }
    sqlite3_extended_result_codes(handle_, 1);
  }
  ~Database() {
    for (auto& [sql, idle] : idleStatements_) {
      for (sqlite3_stmt* statement : idle) sqlite3_finalize(statement);
    }
    sqlite3_close(handle_);  // every Statement has given its statement back by now (RAII)
  }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  sqlite3* handle() const { return handle_; }
  const std::string& path() const { return path_; }

  [[noreturn]] void Throw(const std::string& context) const {
    ThrowFor(sqlite3_extended_errcode(handle_), context + ": " + sqlite3_errmsg(handle_));
  }

  // For statements without parameters or results (schema, pragmas, transaction control).
  void Exec(const char* sql) {
    char* message = nullptr;
    const int rc = sqlite3_exec(handle_, sql, nullptr, nullptr, &message);
    if (rc != SQLITE_OK) {
      const std::string reason = message ? message : sqlite3_errmsg(handle_);
      sqlite3_free(message);
      ThrowFor(rc, std::string(sql) + ": " + reason);
    }
  }

  // A prepared statement for `sql`: one used before and given back, or a new one. Each is
  // parsed once per connection, not per call: parsing was most of what recording a
  // frame cost.
  sqlite3_stmt* TakeStatement(const std::string& sql) {
    std::vector<sqlite3_stmt*>& idle = idleStatements_[sql];
    if (!idle.empty()) {
      sqlite3_stmt* statement = idle.back();
      idle.pop_back();
      return statement;
    }
    sqlite3_stmt* statement = nullptr;
    if (sqlite3_prepare_v3(handle_, sql.c_str(), -1, SQLITE_PREPARE_PERSISTENT, &statement, nullptr) != SQLITE_OK) {
      Throw("prepare " + sql);
    }
    return statement;
  }
  // Resets the statement and keeps it for the next TakeStatement of its SQL.
  void GiveBack(const std::string& sql, sqlite3_stmt* statement) {
    sqlite3_reset(statement);
    sqlite3_clear_bindings(statement);
    idleStatements_[sql].push_back(statement);
  }

  int Changes() const { return sqlite3_changes(handle_); }
  int64_t LastInsertRowId() const { return sqlite3_last_insert_rowid(handle_); }

 private:
  // A full disk (or a file at its size limit) and a failing one are told apart from
  // every other failure: the caller answers them with "no room" and retries later.
  [[noreturn]] void ThrowFor(int rc, const std::string& what) const {
    const int primary = rc & 0xff;
    if (primary == SQLITE_FULL || primary == SQLITE_IOERR) {
      throw JobStoreFullError(path_ + ": " + what +
                              " (the disk holding the job database is full or failing; nothing of this "
                              "write was kept)");
    }
    throw JobStoreError(path_ + ": " + what);
  }

  std::string path_;
  sqlite3* handle_ = nullptr;
  std::unordered_map<std::string, std::vector<sqlite3_stmt*>> idleStatements_;
};

class Statement {
 public:
  Statement(Database& db, std::string sql) : db_(db), sql_(std::move(sql)), handle_(db.TakeStatement(sql_)) {}
  ~Statement() { db_.GiveBack(sql_, handle_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Parameters are numbered from 1, as in SQLite.
  Statement& Bind(int index, int64_t value) {
    return Check(sqlite3_bind_int64(handle_, index, value));
  }
  Statement& Bind(int index, double value) {
    return Check(sqlite3_bind_double(handle_, index, value));
  }
  Statement& Bind(int index, std::string_view value) {
    return Check(sqlite3_bind_text(handle_, index, value.data(), static_cast<int>(value.size()),
                                   SQLITE_TRANSIENT));
  }

  // True while a row is ready; false when done.
  bool Step() {
    const int rc = sqlite3_step(handle_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    db_.Throw(std::string("step ") + sqlite3_sql(handle_));
  }
  void Run() {
    while (Step()) {
    }
  }
  // Ready to run again with new bindings.
  void Reset() { sqlite3_reset(handle_); }

  // Columns are numbered from 0, as in SQLite.
  int64_t Int64(int column) const { return sqlite3_column_int64(handle_, column); }
  bool IsNull(int column) const { return sqlite3_column_type(handle_, column) == SQLITE_NULL; }
  int Int(int column) const { return static_cast<int>(Int64(column)); }
  uint64_t UInt64(int column) const { return static_cast<uint64_t>(Int64(column)); }
  double Double(int column) const { return sqlite3_column_double(handle_, column); }
  std::string Text(int column) const {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(handle_, column));
    return text ? std::string(text, sqlite3_column_bytes(handle_, column)) : std::string();
  }

 private:
  Statement& Check(int rc) {
    if (rc != SQLITE_OK) db_.Throw(std::string("bind ") + sqlite3_sql(handle_));
    return *this;
  }

  Database& db_;
  std::string sql_;
  sqlite3_stmt* handle_ = nullptr;
};

// kWrite (BEGIN IMMEDIATE) takes the write lock up front, so a read-then-write (claim,
// counters, merge-patch) cannot interleave with another connection's write; kRead gives
// several reads one consistent snapshot. Rolls back unless committed, so an exception
// leaves the file as it was.
class Transaction {
 public:
  enum class Mode { kRead, kWrite };
  explicit Transaction(Database& db, Mode mode = Mode::kWrite) : db_(db) {
    db_.Exec(mode == Mode::kWrite ? "BEGIN IMMEDIATE" : "BEGIN DEFERRED");
  }
  ~Transaction() {
    if (!committed_) sqlite3_exec(db_.handle(), "ROLLBACK", nullptr, nullptr, nullptr);
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;

  void Commit() {
    db_.Exec("COMMIT");
    committed_ = true;
  }

 private:
  Database& db_;
  bool committed_ = false;
};

}  // namespace sqlite

// ---------------------------------------------------------------------------------------
// Schema

namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

// Migrations[v] takes a file from user_version v to v + 1; a new schema version appends one.
// The scene JSON and the per-frame counts live in side tables so that a jobs row stays a
// few hundred bytes: List scans it without touching megabytes of scene or 100,000 frames.
constexpr std::array<const char*, JobStore::kSchemaVersion> kMigrations = {{
    R"sql(
      CREATE TABLE jobs (
        id            INTEGER PRIMARY KEY AUTOINCREMENT,
        name          TEXT    NOT NULL,
        scene_hash    TEXT    NOT NULL,
        first_frame   INTEGER NOT NULL,
        last_frame    INTEGER NOT NULL CHECK (last_frame >= first_frame),
        strategy      TEXT    NOT NULL,
        bin_width     INTEGER NOT NULL,
        tolerance     REAL    NOT NULL,
        priority      INTEGER NOT NULL,
        options       TEXT    NOT NULL,
        state         TEXT    NOT NULL
                      CHECK (state IN ('queued', 'running', 'completed', 'failed', 'canceled')),
        error         TEXT    NOT NULL DEFAULT '',
        submitted_ms  INTEGER NOT NULL,
        started_ms    INTEGER NOT NULL DEFAULT 0,
        finished_ms   INTEGER NOT NULL DEFAULT 0,
        frames_done   INTEGER NOT NULL DEFAULT 0,
        traced_pixels INTEGER NOT NULL DEFAULT 0,
        copied_pixels INTEGER NOT NULL DEFAULT 0,
        stats         TEXT    NOT NULL DEFAULT '{}'
      );
      CREATE INDEX jobs_by_claim_order ON jobs (state, priority DESC, id);
      CREATE TABLE job_scenes (
        job_id     INTEGER PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
        scene_json TEXT NOT NULL
      );
      CREATE TABLE job_frames (
        job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
        frame  INTEGER NOT NULL,
        traced INTEGER NOT NULL,
        copied INTEGER NOT NULL,
        PRIMARY KEY (job_id, frame)
      ) WITHOUT ROWID;
    )sql",
    // The scene's frame size and motion, read at submit. Older rows get their size from
    // BackfillFrameSizes; their motion stays NULL (unknown).
    R"sql(
      ALTER TABLE jobs ADD COLUMN width  INTEGER NOT NULL DEFAULT 0;
      ALTER TABLE jobs ADD COLUMN height INTEGER NOT NULL DEFAULT 0;
      ALTER TABLE jobs ADD COLUMN camera_or_lights_change INTEGER;
    )sql",
    // The plan a job runs with, kept across restarts so that a resumed job plans the same
    // bins; and the identity of the frame store this file belongs to.
    R"sql(
      ALTER TABLE jobs ADD COLUMN plan TEXT NOT NULL DEFAULT '{}';
      CREATE TABLE store_identity (
        one_row  INTEGER PRIMARY KEY CHECK (one_row = 1),
        store_id TEXT NOT NULL
      );
    )sql",
    // Each job's events; the assets each job names, so that an asset goes with the last job
    // naming it; and the jobs deleted whose folders are still to be removed. Events are not
    // tied to their job by a foreign key: a job's "deleted" event outlives it.
    R"sql(
      CREATE TABLE job_events (
        seq     INTEGER PRIMARY KEY AUTOINCREMENT,
        job_id  INTEGER NOT NULL,
        time_ms INTEGER NOT NULL,
        type    TEXT    NOT NULL,
        message TEXT    NOT NULL,
        fields  TEXT    NOT NULL DEFAULT '{}'
      );
      CREATE INDEX job_events_by_job ON job_events (job_id, seq);
      CREATE TABLE job_assets (
        job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
        sha256 TEXT    NOT NULL,
        PRIMARY KEY (job_id, sha256)
      ) WITHOUT ROWID;
      CREATE INDEX job_assets_by_hash ON job_assets (sha256);
      CREATE TABLE job_deletions (job_id INTEGER PRIMARY KEY);
      CREATE INDEX jobs_by_finish ON jobs (finished_ms, id)
        WHERE state IN ('completed', 'failed', 'canceled');
    )sql",
}};

// The texture assets a stored scene uses: canonical scenes name them as "asset":"<sha256>".
// Read from the text, so that a scene of millions of triangles is not parsed for it.
std::vector<std::string> TextureAssetsOfScene(const std::string& sceneJson) {
  static const std::string kKey = "\"asset\":\"";
  constexpr size_t kHashLength = 64;
  std::vector<std::string> hashes;
  for (size_t at = sceneJson.find(kKey); at != std::string::npos; at = sceneJson.find(kKey, at + 1)) {
    const size_t begin = at + kKey.size();
    if (begin + kHashLength < sceneJson.size() && sceneJson[begin + kHashLength] == '"') {
      hashes.push_back(sceneJson.substr(begin, kHashLength));
    }
  }
  return hashes;
}

void InsertAssetNames(Database& db, int64_t id, const std::vector<std::string>& hashes) {
  Statement insert(db, "INSERT OR IGNORE INTO job_assets (job_id, sha256) VALUES (?1, ?2)");
  for (const std::string& hash : hashes) {
    insert.Reset();
    insert.Bind(1, id).Bind(2, hash);
    insert.Run();
  }
}

// Schema 4 names each job's assets; jobs stored before it name the textures their scenes
// use (the files they were submitted with are no longer needed by anyone).
void BackfillAssetNames(Database& db) {
  std::vector<std::pair<int64_t, std::vector<std::string>>> named;
  {
    Statement scenes(db, "SELECT job_id, scene_json FROM job_scenes");
    while (scenes.Step()) named.emplace_back(scenes.Int64(0), TextureAssetsOfScene(scenes.Text(1)));
  }
  for (const auto& [id, hashes] : named) InsertAssetNames(db, id, hashes);
}

// The scene's render.width/height, read without parsing the rest of the scene (a stored
// scene may inline millions of triangles). 0x0 when the JSON has no render size, which a
// stored, validated scene always has.
FrameSize RenderSizeOfScene(const std::string& sceneJson) {
  // The callback drops every top-level member but "render" as the parser reaches it, so
  // meshes are tokenized but never stored.
  nlohmann::json::parser_callback_t keepRenderOnly = [](int depth, nlohmann::json::parse_event_t event,
                                                        nlohmann::json& parsed) {
    return !(event == nlohmann::json::parse_event_t::key && depth == 1 && parsed != "render");
  };
  try {
    const nlohmann::json scene = nlohmann::json::parse(sceneJson, keepRenderOnly);
    const nlohmann::json& render = scene.at("render");
    return FrameSize{render.at("width").get<int>(), render.at("height").get<int>()};
  } catch (const nlohmann::json::exception&) {
    return FrameSize{};
  }
}

// Schema 2 stores each job's frame size; rows written before it get theirs from their
// scene, once, here.
void BackfillFrameSizes(Database& db) {
  std::vector<std::pair<int64_t, FrameSize>> sizes;
  {
    Statement scenes(db, "SELECT job_id, scene_json FROM job_scenes");
    while (scenes.Step()) sizes.emplace_back(scenes.Int64(0), RenderSizeOfScene(scenes.Text(1)));
  }
  Statement update(db, "UPDATE jobs SET width = ?2, height = ?3 WHERE id = ?1");
  for (const auto& [id, size] : sizes) {
    update.Reset();
    update.Bind(1, id).Bind(2, int64_t{size.width}).Bind(3, int64_t{size.height});
    update.Run();
  }
}

int ReadSchemaVersion(Database& db) {
  Statement statement(db, "PRAGMA user_version");
  statement.Step();
  return statement.Int(0);
}

// PRAGMA takes no bound parameters; the version is one of our own integers, never input.
void WriteSchemaVersion(Database& db, int version) {
  db.Exec(("PRAGMA user_version = " + std::to_string(version)).c_str());
}

// Inside one IMMEDIATE transaction, so two processes opening a new file at once cannot
// both create the tables, and a failed migration leaves the old schema intact.
void MigrateForward(Database& db) {
  Transaction transaction(db);
  const int version = ReadSchemaVersion(db);
  if (version > JobStore::kSchemaVersion) {
    throw JobStoreError(db.path() + ": job database schema version " + std::to_string(version) +
                        " is newer than this coordinator understands (" +
                        std::to_string(JobStore::kSchemaVersion) +
                        "); run a newer coordinator or use another file");
  }
  for (int next = version; next < JobStore::kSchemaVersion; ++next) db.Exec(kMigrations[next]);
  if (version >= 1 && version < 2) BackfillFrameSizes(db);
  if (version >= 1 && version < 4) BackfillAssetNames(db);
  if (version != JobStore::kSchemaVersion) WriteSchemaVersion(db, JobStore::kSchemaVersion);
  transaction.Commit();
}

void ConfigureConnection(Database& db) {
  sqlite3_busy_timeout(db.handle(), kBusyTimeoutMs);
  // The first statement that reads the file: a non-SQLite file fails here.
  if (sqlite3_exec(db.handle(), "PRAGMA journal_mode = WAL", nullptr, nullptr, nullptr) !=
      SQLITE_OK) {
    db.Throw("cannot open job database");
  }
  // In WAL mode NORMAL never corrupts the file and loses nothing when the process dies; only
  // an OS crash may drop the last commits. FULL would fsync once per finished frame.
  db.Exec("PRAGMA synchronous = NORMAL");
  db.Exec("PRAGMA foreign_keys = ON");
}

// The columns every record read selects, in the order ReadRecord expects.
const std::string kSelectJobColumns =
    "SELECT id, name, scene_hash, first_frame, last_frame, strategy, bin_width, tolerance, "
    "priority, options, state, error, submitted_ms, started_ms, finished_ms, frames_done, "
    "traced_pixels, copied_pixels, stats, width, height, camera_or_lights_change, plan FROM jobs ";

// Submit writes only names from kStrategyNames, so another one means the file was changed
// behind the coordinator's back: guessing what the job wanted would render the wrong thing.
Strategy StrategyOfRow(uint64_t id, const std::string& name) {
  const std::optional<Strategy> strategy = StrategyFromString(name);
  if (!strategy) {
    throw JobStoreError("job " + std::to_string(id) + " has strategy '" + name +
                        "'; expected one this coordinator knows");
  }
  return *strategy;
}

JobRecord ReadRecord(const Statement& row) {
  JobRecord record;
  record.id = row.UInt64(0);
  record.spec.name = row.Text(1);
  record.spec.sceneHash = row.Text(2);
  record.spec.firstFrame = row.Int(3);
  record.spec.lastFrame = row.Int(4);
  record.spec.strategy = StrategyOfRow(record.id, row.Text(5));
  record.spec.binWidth = row.Int(6);
  record.spec.tolerance = row.Double(7);
  record.spec.priority = row.Int(8);
  record.spec.options = nlohmann::json::parse(row.Text(9));
  // The CHECK constraint on the column keeps this lookup total.
  record.state = JobStateFromString(row.Text(10)).value_or(JobState::kFailed);
  record.error = row.Text(11);
  record.submittedMs = row.Int64(12);
  record.startedMs = row.Int64(13);
  record.finishedMs = row.Int64(14);
  record.framesDone = row.Int(15);
  record.tracedPixels = row.UInt64(16);
  record.copiedPixels = row.UInt64(17);
  record.stats = nlohmann::json::parse(row.Text(18));
  record.spec.frameSize = FrameSize{row.Int(19), row.Int(20)};
  if (!row.IsNull(21)) record.spec.cameraOrLightsChange = row.Int(21) != 0;
  record.plan = nlohmann::json::parse(row.Text(22));
  return record;
}

std::optional<JobRecord> LoadRecordRow(Database& db, uint64_t id) {
  Statement statement(db, kSelectJobColumns + "WHERE id = ?1");
  statement.Bind(1, static_cast<int64_t>(id));
  if (!statement.Step()) return std::nullopt;
  return ReadRecord(statement);
}

void LoadSceneJson(Database& db, JobRecord& record) {
  Statement statement(db, "SELECT scene_json FROM job_scenes WHERE job_id = ?1");
  statement.Bind(1, static_cast<int64_t>(record.id));
  if (statement.Step()) record.spec.sceneJson = statement.Text(0);
}

void LoadTracedPerFrame(Database& db, JobRecord& record) {
  record.tracedPerFrame.assign(static_cast<size_t>(record.FrameCount()), -1);
  Statement statement(db, "SELECT frame, traced FROM job_frames WHERE job_id = ?1");
  statement.Bind(1, static_cast<int64_t>(record.id));
  while (statement.Step()) {
    const int64_t index = statement.Int64(0) - record.spec.firstFrame;
    if (index >= 0 && index < record.FrameCount()) {
      record.tracedPerFrame[static_cast<size_t>(index)] = statement.Int64(1);
    }
  }
}

std::optional<JobRecord> LoadFullRecord(Database& db, uint64_t id) {
  std::optional<JobRecord> record = LoadRecordRow(db, id);
  if (!record) return std::nullopt;
  LoadSceneJson(db, *record);
  LoadTracedPerFrame(db, *record);
  return record;
}

std::optional<JobState> ReadState(Database& db, uint64_t id) {
  Statement statement(db, "SELECT state FROM jobs WHERE id = ?1");
  statement.Bind(1, static_cast<int64_t>(id));
  if (!statement.Step()) return std::nullopt;
  return JobStateFromString(statement.Text(0));
}

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

// stats stay a JSON object: a null patch merges nothing (RFC 7386 would replace the whole
// object with null), any other non-object is refused.
void MergeStats(Database& db, uint64_t id, const nlohmann::json& patch) {
  if (patch.is_null()) return;
  if (!patch.is_object()) {
    throw std::invalid_argument("job " + std::to_string(id) +
                                ": stats must be a JSON object, got " + patch.type_name());
  }
  Statement read(db, "SELECT stats FROM jobs WHERE id = ?1");
  read.Bind(1, static_cast<int64_t>(id));
  if (!read.Step()) return;
  nlohmann::json stats = nlohmann::json::parse(read.Text(0));
  stats.merge_patch(patch);
  Statement write(db, "UPDATE jobs SET stats = ?2 WHERE id = ?1");
  write.Bind(1, static_cast<int64_t>(id)).Bind(2, stats.dump());
  write.Run();
}

// "frames 10..19", "frame 7", "frames 0..1, 4, 8..9": frames as runs, ascending.
std::vector<std::pair<int, int>> FrameRuns(std::vector<int> frames) {
  std::sort(frames.begin(), frames.end());
  frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
  std::vector<std::pair<int, int>> runs;
  for (int frame : frames) {
    if (!runs.empty() && runs.back().second + 1 == frame) {
      runs.back().second = frame;
    } else {
      runs.emplace_back(frame, frame);
    }
  }
  return runs;
}

std::string RunsText(const std::vector<std::pair<int, int>>& runs) {
  std::string text;
  for (const auto& [first, last] : runs) {
    if (!text.empty()) text += ", ";
    text += first == last ? std::to_string(first) : std::to_string(first) + ".." + std::to_string(last);
  }
  return text;
}

EventDraft FramesWrittenEvent(const std::vector<int>& frames) {
  const std::vector<std::pair<int, int>> runs = FrameRuns(frames);
  size_t count = 0;
  nlohmann::json ranges = nlohmann::json::array();
  for (const auto& [first, last] : runs) {
    count += static_cast<size_t>(last - first + 1);
    ranges.push_back({first, last});
  }
  std::string message;
  if (runs.size() == 1) {
    message = runs[0].first == runs[0].second ? "frame " + std::to_string(runs[0].first) + " written"
                                              : "frames " + RunsText(runs) + " written";
  } else {
    message = std::to_string(count) + " frames written: " + RunsText(runs);
  }
  return {"frames_written", message,
          {{"first", runs.front().first}, {"last", runs.back().second}, {"count", count}, {"ranges", ranges}}};
}

// The job's recorded frames that no frames_written event names, ascending: those a
// coordinator that stopped without its goodbye had recorded but not yet told.
std::vector<int> RecordedFramesNeverTold(Database& db, uint64_t id) {
  std::set<int> told;
  Statement events(db, "SELECT fields FROM job_events WHERE job_id = ?1 AND type = 'frames_written'");
  events.Bind(1, static_cast<int64_t>(id));
  while (events.Step()) {
    const nlohmann::json fields = nlohmann::json::parse(events.Text(0), nullptr, false);
    if (!fields.is_object() || !fields.contains("ranges") || !fields["ranges"].is_array()) continue;
    for (const nlohmann::json& range : fields["ranges"]) {
      if (range.size() != 2 || !range[0].is_number_integer() || !range[1].is_number_integer()) continue;
      for (int frame = range[0].get<int>(); frame <= range[1].get<int>(); ++frame) told.insert(frame);
    }
  }
  std::vector<int> untold;
  Statement frames(db, "SELECT frame FROM job_frames WHERE job_id = ?1 ORDER BY frame");
  frames.Bind(1, static_cast<int64_t>(id));
  while (frames.Step()) {
    if (told.count(frames.Int(0)) == 0) untold.push_back(frames.Int(0));
  }
  return untold;
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

JobEvent ReadEvent(const Statement& row) {
  JobEvent event;
  event.seq = row.UInt64(0);
  event.job = row.UInt64(1);
  event.timeMs = row.Int64(2);
  event.type = row.Text(3);
  event.message = row.Text(4);
  event.fields = nlohmann::json::parse(row.Text(5), nullptr, false);
  if (!event.fields.is_object()) event.fields = nlohmann::json::object();
  return event;
}

// ",queued,running,": a set of names matched in SQL with instr(), so the statement's text
// stays a literal whatever the number of names; nullopt (SQL NULL) matches all.
template <typename T, typename Name>
std::optional<std::string> NameSet(const std::vector<T>& values, Name name) {
  if (values.empty()) return std::nullopt;
  std::string set = ",";
  for (const T& value : values) set += std::string(name(value)) + ",";
  return set;
}

// The WHERE clause JobStore::Query pages and counts with: ?1 states, ?2 strategies (as
// NameSet writes them), ?3 a substring of the name; NULL matches every job. lower() folds
// ASCII letters only, as SQLite's LIKE does.
const std::string kJobFilter =
    "WHERE (?1 IS NULL OR instr(?1, ',' || state || ',') > 0) "
    "AND (?2 IS NULL OR instr(?2, ',' || strategy || ',') > 0) "
    "AND (?3 IS NULL OR instr(lower(name), lower(?3)) > 0) ";

void BindJobFilter(Statement& statement, const JobQuery& query) {
  if (auto states = NameSet(query.states, [](JobState state) { return ToString(state); })) {
    statement.Bind(1, *states);
  }
  if (auto strategies = NameSet(query.strategies, [](Strategy strategy) { return StrategyName(strategy); })) {
    statement.Bind(2, *strategies);
  }
  if (!query.nameContains.empty()) statement.Bind(3, query.nameContains);
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
                   "camera_or_lights_change) "
                   "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, 'queued', ?10, ?11, ?12, ?13)");
  insert.Bind(1, spec.name).Bind(2, spec.sceneHash);
  insert.Bind(3, int64_t{spec.firstFrame}).Bind(4, int64_t{spec.lastFrame});
  insert.Bind(5, StrategyName(spec.strategy)).Bind(6, int64_t{spec.binWidth}).Bind(7, spec.tolerance);
  insert.Bind(8, int64_t{spec.priority}).Bind(9, spec.options.dump()).Bind(10, nowMs_());
  insert.Bind(11, int64_t{spec.frameSize.width}).Bind(12, int64_t{spec.frameSize.height});
  if (spec.cameraOrLightsChange) insert.Bind(13, int64_t{*spec.cameraOrLightsChange ? 1 : 0});
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
  untold_.erase(id);
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
  const auto untold = untold_.find(id);
  std::vector<int> frames = untold == untold_.end() ? std::vector<int>{} : untold->second.frames;
  frames.push_back(frame);
  std::vector<JobEvent> recorded;
  if (frames.size() >= kFramesPerEvent) Record(id, FramesWrittenEvent(frames), recorded);
  transaction.Commit();
  if (!recorded.empty()) {
    Announce(recorded, {id});
  } else {
    UntoldFrames& owed = untold_[id];
    if (owed.frames.empty()) owed.sinceMs = now;
    owed.frames.push_back(frame);
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
  if (auto untold = untold_.find(id); untold != untold_.end()) {
    std::vector<int>& owed = untold->second.frames;
    for (int frame : frames) owed.erase(std::remove(owed.begin(), owed.end(), frame), owed.end());
    if (owed.empty()) untold_.erase(untold);
  }
}

uint64_t JobStore::AppendEvent(uint64_t id, const EventDraft& event) {
  std::lock_guard<std::mutex> lock(mutex_);
  Transaction transaction(*db_);
  if (!ReadState(*db_, id)) return 0;  // deleted meanwhile: no event outlives its job but "deleted"
  std::vector<JobEvent> recorded;
  Record(id, event, recorded);
  transaction.Commit();
  Announce(recorded, {});
  return recorded.back().seq;
}

void JobStore::FlushFrameEvents() {
  std::lock_guard<std::mutex> lock(mutex_);
  const int64_t now = nowMs_();
  std::vector<uint64_t> due;
  for (const auto& [id, untold] : untold_) {
    if (now - untold.sinceMs >= kFrameEventIntervalMs) due.push_back(id);
  }
  if (due.empty()) return;
  Transaction transaction(*db_);
  std::vector<JobEvent> recorded;
  std::vector<uint64_t> told;
  for (uint64_t id : due) RecordUntoldFrames(id, recorded, told);
  transaction.Commit();
  Announce(recorded, told);
}

std::vector<JobEvent> JobStore::Events(const EventQuery& query) const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_,
                      "SELECT seq, job_id, time_ms, type, message, fields FROM job_events "
                      "WHERE seq > ?1 AND (?2 IS NULL OR job_id = ?2) ORDER BY seq LIMIT ?3");
  statement.Bind(1, static_cast<int64_t>(std::min<uint64_t>(query.afterSeq, INT64_MAX)));
  if (query.job) statement.Bind(2, static_cast<int64_t>(*query.job));
  statement.Bind(3, static_cast<int64_t>(std::min<size_t>(query.limit, INT64_MAX)));
  std::vector<JobEvent> events;
  while (statement.Step()) events.push_back(ReadEvent(statement));
  return events;
}

uint64_t JobStore::LastEventSeq() const {
  std::lock_guard<std::mutex> lock(mutex_);
  Statement statement(*db_, "SELECT COALESCE(MAX(seq), 0) FROM job_events");
  statement.Step();
  return statement.UInt64(0);
}

uint64_t JobStore::AddEventListener(EventListener listener) {
  std::lock_guard<std::mutex> lock(mutex_);
  const uint64_t id = nextListenerId_++;
  listeners_[id] = std::move(listener);
  return id;
}

void JobStore::RemoveEventListener(uint64_t listenerId) {
  std::lock_guard<std::mutex> lock(mutex_);
  listeners_.erase(listenerId);
}

void JobStore::Record(uint64_t id, const EventDraft& event, std::vector<JobEvent>& recorded) {
  JobEvent written;
  written.job = id;
  written.timeMs = nowMs_();
  written.type = event.type;
  written.message = event.message;
  if (event.fields.is_object()) written.fields = event.fields;
  Statement insert(*db_, "INSERT INTO job_events (job_id, time_ms, type, message, fields) VALUES (?1, ?2, ?3, ?4, ?5)");
  insert.Bind(1, static_cast<int64_t>(id)).Bind(2, written.timeMs).Bind(3, written.type);
  insert.Bind(4, written.message).Bind(5, written.fields.dump());
  insert.Run();
  written.seq = static_cast<uint64_t>(db_->LastInsertRowId());
  recorded.push_back(std::move(written));
}

void JobStore::RecordUntoldFrames(uint64_t id, std::vector<JobEvent>& recorded, std::vector<uint64_t>& told) {
  const auto untold = untold_.find(id);
  if (untold == untold_.end() || untold->second.frames.empty()) return;
  Record(id, FramesWrittenEvent(untold->second.frames), recorded);
  told.push_back(id);
}

void JobStore::RecordUntoldFramesOfCrash(uint64_t id, std::vector<JobEvent>& recorded) {
  const std::vector<int> untold = RecordedFramesNeverTold(*db_, id);
  for (size_t begin = 0; begin < untold.size(); begin += kFramesPerEvent) {
    const size_t end = std::min(untold.size(), begin + kFramesPerEvent);
    EventDraft event = FramesWrittenEvent({untold.begin() + static_cast<std::ptrdiff_t>(begin),
                                           untold.begin() + static_cast<std::ptrdiff_t>(end)});
    event.message += " (recovered: the coordinator stopped before telling them)";
    event.fields["recovered"] = true;
    Record(id, event, recorded);
  }
}

void JobStore::Announce(const std::vector<JobEvent>& recorded, const std::vector<uint64_t>& told) {
  for (uint64_t id : told) untold_.erase(id);
  for (const JobEvent& event : recorded) {
    for (const auto& [listenerId, listener] : listeners_) listener(event);
  }
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
