#include "coordinator/farm/worker_bans.h"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace tcfarm {

WorkerBans::WorkerBans(std::filesystem::path file) : file_(std::move(file)) {
  std::ifstream in(file_);
  if (!in) return;  // no ban yet
  std::stringstream text;
  text << in.rdbuf();
  try {
    const nlohmann::json file = nlohmann::json::parse(text.str());
    for (const nlohmann::json& entry : file.at("bans")) {
      WorkerBan ban{entry.at("principal").get<std::string>(), entry.value("name", std::string()),
                    entry.value("why", std::string()), entry.value("banned_ms", int64_t{0})};
      bans_[ban.principal] = std::move(ban);
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(file_.string() + ": not a list of worker bans ({\"bans\": [{\"principal\": ...}]}): " +
                             e.what());
  }
}

void WorkerBans::Add(const WorkerBan& ban) {
  std::lock_guard<std::mutex> lock(mutex_);
  bans_[ban.principal] = ban;
  Save();
}

bool WorkerBans::Remove(const std::string& principal) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!bans_.erase(principal)) return false;
  Save();
  return true;
}

std::vector<WorkerBan> WorkerBans::List() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<WorkerBan> bans;
  for (const auto& [principal, ban] : bans_) bans.push_back(ban);
  return bans;
}

// Temp file and rename: a crash leaves the old list or the new one, never half of one.
void WorkerBans::Save() const {
  nlohmann::json bans = nlohmann::json::array();
  for (const auto& [principal, ban] : bans_) {
    bans.push_back({{"principal", ban.principal}, {"name", ban.name}, {"why", ban.why}, {"banned_ms", ban.bannedMs}});
  }
  const std::filesystem::path partial = file_.string() + ".partial";
  {
    std::ofstream out(partial, std::ios::trunc);
    out << nlohmann::json{{"bans", bans}}.dump(2) << '\n';
    out.flush();
    if (!out) throw std::runtime_error("cannot write " + partial.string());
  }
  std::error_code error;
  std::filesystem::rename(partial, file_, error);
  if (error) throw std::runtime_error("cannot replace " + file_.string() + ": " + error.message());
}

}  // namespace tcfarm
