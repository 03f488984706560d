// Which frame store a job database belongs to, checked at start: a job's frames live in
// STORE/<job>/, named by the job's id, so a database over someone else's store (or a
// fresh one over a store with jobs) would hand out ids whose folders hold another job's
// frames, and overwrite them.
//
// The store carries an identity file, STORE/store-id (a random id made at its first
// start); the database records the id of the store it belongs to (JobStore::StoreId).
// BindDatabaseToStore accepts only a matching pair (or a new one, which it binds), and
// makes the database's next job ids lie above every job folder in the store, whatever
// happened before.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "coordinator/jobs/job_store.h"

namespace tcfarm {

// A database and a store that do not belong together; the message names both and the way out.
class StoreMismatchError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The store's identity file's id; nullopt when it has none yet.
std::optional<std::string> ReadStoreId(const std::filesystem::path& storeRoot);
// The job folders (STORE/<decimal id>/) in the store, ascending.
std::vector<uint64_t> JobFolders(const std::filesystem::path& storeRoot);

// Binds `database` to the store at storeRoot, or throws StoreMismatchError when:
//  - the database records another store's id, or the store has none while the database
//    records one (the database was moved away from its store);
//  - the database has no store recorded and the store already has job folders (a fresh
//    database over an old store; an old pair from before identity files, whose database
//    has jobs, is bound as it is).
// adoptStore (--adopt-store) binds such a pair anyway, with the store's identity, as long
// as no job folder in the store has the id of a job in the database; ids of new jobs start
// above the highest folder, so no folder is ever shared.
void BindDatabaseToStore(JobStore& database, const std::filesystem::path& storeRoot, bool adoptStore);

}  // namespace tcfarm
