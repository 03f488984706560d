#include "coordinator/jobs/job_schema.h"

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "coordinator/jobs/job_rows.h"

namespace tcfarm::jobs {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;

// Long enough to ride out another connection's commit (another process on the same file),
// short enough that a wedged lock surfaces as an error instead of a hung coordinator.
constexpr int kBusyTimeoutMs = 5000;

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
    // Whether the scene's meshes deform, read at submit (NULL: unknown, for older rows);
    // and the segment prices exact jobs measured per scene, for auto's model (PriceBook).
    R"sql(
      ALTER TABLE jobs ADD COLUMN deforming_meshes INTEGER;
      CREATE TABLE scene_prices (
        scene_hash  TEXT    PRIMARY KEY,
        deforming   INTEGER,
        start_price REAL    NOT NULL,
        frame_price REAL    NOT NULL,
        measured_ms INTEGER NOT NULL
      );
      CREATE INDEX scene_prices_by_time ON scene_prices (measured_ms);
    )sql",
}};

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

}  // namespace

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

}  // namespace tcfarm::jobs
