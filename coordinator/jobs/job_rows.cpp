#include "coordinator/jobs/job_rows.h"

#include <cstddef>
#include <stdexcept>

namespace tcfarm::jobs {

using sqlite::Database;
using sqlite::Statement;

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

const std::string kSelectJobColumns =
    "SELECT id, name, scene_hash, first_frame, last_frame, strategy, bin_width, tolerance, "
    "priority, options, state, error, submitted_ms, started_ms, finished_ms, frames_done, "
    "traced_pixels, copied_pixels, stats, width, height, camera_or_lights_change, plan, deforming_meshes FROM jobs ";

namespace {

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

}  // namespace

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
  if (!row.IsNull(23)) record.spec.deformingMeshes = row.Int(23) != 0;
  return record;
}

std::optional<JobRecord> LoadRecordRow(Database& db, uint64_t id) {
  Statement statement(db, kSelectJobColumns + "WHERE id = ?1");
  statement.Bind(1, static_cast<int64_t>(id));
  if (!statement.Step()) return std::nullopt;
  return ReadRecord(statement);
}

namespace {

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

}  // namespace

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

namespace {

// ",queued,running,": a set of names matched in SQL with instr(), so the statement's text
// stays a literal whatever the number of names; nullopt (SQL NULL) matches all.
template <typename T, typename Name>
std::optional<std::string> NameSet(const std::vector<T>& values, Name name) {
  if (values.empty()) return std::nullopt;
  std::string set = ",";
  for (const T& value : values) set += std::string(name(value)) + ",";
  return set;
}

}  // namespace

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


}  // namespace tcfarm::jobs
