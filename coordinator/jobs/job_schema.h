// The job database's connection settings and schema: the migrations that take a file of
// any older schema version to JobStore::kSchemaVersion, and the backfills they need.
#pragma once

#include "coordinator/jobs/sqlite_database.h"

namespace tcfarm::jobs {

// Busy timeout, WAL journal, synchronous NORMAL, foreign keys. Throws JobStoreError when
// the file is not a database.
void ConfigureConnection(sqlite::Database& db);
// Creates the tables or migrates an older schema forward, in one transaction. Throws
// JobStoreError for a file whose schema is newer than this code knows.
void MigrateForward(sqlite::Database& db);

}  // namespace tcfarm::jobs
