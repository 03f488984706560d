#include "coordinator/store/store_identity.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <random>
#include <system_error>

namespace tcfarm {
namespace {

constexpr const char* kIdentityFile = "store-id";
constexpr const char* kWayOut =
    "; point --store and --db at a store and the database that belong together, or start with --adopt-store to "
    "bind this database to this store (its new job ids then start above the store's highest job folder)";

std::string NewStoreId() {
  std::random_device random;
  std::string id;
  for (int i = 0; i < 4; ++i) {
    char word[9];
    std::snprintf(word, sizeof word, "%08x", static_cast<unsigned>(random()));
    id += word;
  }
  return id;
}

// Temp file and rename: a store never has half an identity.
void WriteStoreId(const std::filesystem::path& storeRoot, const std::string& id) {
  const std::filesystem::path path = storeRoot / kIdentityFile;
  std::filesystem::path partial = path;
  partial += ".partial";
  {
    std::ofstream out(partial, std::ios::trunc);
    out << id << "\n";
    if (!out.flush()) throw std::runtime_error("cannot write the store's identity file " + partial.string());
  }
  std::error_code error;
  std::filesystem::rename(partial, path, error);
  if (error) throw std::runtime_error("cannot move " + partial.string() + " into place: " + error.message());
}

bool IsDecimal(const std::string& name) {
  return !name.empty() && name.size() <= 19 && std::all_of(name.begin(), name.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string Describe(const std::optional<std::string>& id) { return id ? "store " + *id : "no store"; }

}  // namespace

std::optional<std::string> ReadStoreId(const std::filesystem::path& storeRoot) {
  std::ifstream in(storeRoot / kIdentityFile);
  std::string id;
  if (!(in >> id)) return std::nullopt;
  return id;
}

std::vector<uint64_t> JobFolders(const std::filesystem::path& storeRoot) {
  std::vector<uint64_t> folders;
  std::error_code error;
  for (std::filesystem::directory_iterator it(storeRoot, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (IsDecimal(name) && it->is_directory(error)) folders.push_back(std::stoull(name));
  }
  std::sort(folders.begin(), folders.end());
  return folders;
}

void BindDatabaseToStore(JobStore& database, const std::filesystem::path& storeRoot, bool adoptStore) {
  const std::optional<std::string> storeId = ReadStoreId(storeRoot);
  const std::optional<std::string> recorded = database.StoreId();
  const std::vector<uint64_t> folders = JobFolders(storeRoot);
  const std::string store = "frame store " + storeRoot.string();
  const bool matching = storeId && recorded && *storeId == *recorded;
  if (!matching) {
    std::string mismatch;
    if (recorded) {
      mismatch = "the job database belongs to store " + *recorded + ", but " + store + " is " + Describe(storeId);
    } else if (!folders.empty() && (database.JobCount() == 0 || storeId)) {
      mismatch = "the job database records no store and " + store + " holds " + std::to_string(folders.size()) +
                 " job folders (up to " + std::to_string(folders.back()) +
                 ") that are not its jobs: new jobs would take their ids and overwrite their frames";
    }
    if (!mismatch.empty() && !adoptStore) throw StoreMismatchError(mismatch + kWayOut);
    if (!mismatch.empty()) {
      for (uint64_t folder : folders) {
        if (database.HasJob(folder)) {
          throw StoreMismatchError(mismatch + "; --adopt-store refused: job folder " + std::to_string(folder) +
                                   " of the store has the id of a job of this database, whose frames it would "
                                   "then serve; use a store without that folder");
        }
      }
      std::fprintf(stderr, "tcfarm-coordinator: --adopt-store: %s; bound to it\n", mismatch.c_str());
    }
  }
  std::string id = storeId.value_or("");
  if (id.empty()) {
    id = NewStoreId();
    WriteStoreId(storeRoot, id);
  }
  if (recorded != id) database.SetStoreId(id);
  if (!folders.empty()) database.ReserveJobIdsThrough(folders.back());
}

}  // namespace tcfarm
