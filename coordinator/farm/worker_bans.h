// Workers banned for returning wrong values, kept in the store (worker_bans.json) so that
// a ban outlives the coordinator. A ban names a principal (dispatch/dispatcher.h
// PrincipalOf): a CURVE key, or without CURVE a name and an address. It holds until an
// operator lifts it (DELETE /api/v1/workers/distrusted?principal=P, or
// `tcfarm distrusted --lift`).
//
// Thread-safe: the farm loop adds bans, the HTTP API lists and lifts them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace tcfarm {

struct WorkerBan {
  std::string principal;
  std::string name;  // the worker's name when it was banned
  std::string why;
  int64_t bannedMs = 0;  // unix milliseconds
};

class WorkerBans {
 public:
  // Reads the file if it exists. Throws std::runtime_error naming the file when it cannot
  // be read or is not a list of bans: a coordinator that forgot its bans would trust a
  // worker found lying.
  explicit WorkerBans(std::filesystem::path file);

  // Adds (or replaces) a ban and writes the file; throws std::runtime_error when it cannot.
  void Add(const WorkerBan& ban);
  // False when the principal was not banned.
  bool Remove(const std::string& principal);
  std::vector<WorkerBan> List() const;

 private:
  void Save() const;  // under mutex_

  std::filesystem::path file_;
  mutable std::mutex mutex_;
  std::map<std::string, WorkerBan> bans_;
};

}  // namespace tcfarm
