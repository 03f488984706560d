// Conversions between the job store's rows and its records: the columns a record is read
// from, its side tables (scene, per-frame counts, asset names), events, and the filter
// JobStore::Query pages with.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/jobs/job_store.h"
#include "coordinator/jobs/sqlite_database.h"

namespace tcfarm::jobs {

// The columns every record read selects, in the order ReadRecord expects.
extern const std::string kSelectJobColumns;
// The WHERE clause JobStore::Query pages and counts with; BindJobFilter binds it.
extern const std::string kJobFilter;

JobRecord ReadRecord(const sqlite::Statement& row);
// The jobs row alone, without sceneJson and tracedPerFrame.
std::optional<JobRecord> LoadRecordRow(sqlite::Database& db, uint64_t id);
// With sceneJson and tracedPerFrame.
std::optional<JobRecord> LoadFullRecord(sqlite::Database& db, uint64_t id);
std::optional<JobState> ReadState(sqlite::Database& db, uint64_t id);
// Merge-patches (RFC 7386) `patch` into the job's stats. Throws std::invalid_argument for a
// patch that is not an object (null merges nothing).
void MergeStats(sqlite::Database& db, uint64_t id, const nlohmann::json& patch);
JobEvent ReadEvent(const sqlite::Statement& row);
void BindJobFilter(sqlite::Statement& statement, const JobQuery& query);

// The texture assets a stored scene uses, read from its text.
std::vector<std::string> TextureAssetsOfScene(const std::string& sceneJson);
void InsertAssetNames(sqlite::Database& db, int64_t id, const std::vector<std::string>& hashes);

}  // namespace tcfarm::jobs
