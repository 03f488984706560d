#include "coordinator/jobs/job_event_log.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <set>
#include <string>
#include <utility>

#include "coordinator/jobs/job_rows.h"

namespace tcfarm {
namespace jobs {

using sqlite::Database;
using sqlite::Statement;

namespace {

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

}  // namespace

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

}  // namespace jobs

using jobs::FramesWrittenEvent;
using jobs::ReadEvent;
using jobs::ReadState;
using jobs::RecordedFramesNeverTold;
using sqlite::Statement;
using sqlite::Transaction;

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
  const std::vector<uint64_t> due = untold_.DueAt(now, kFrameEventIntervalMs);
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
  const std::vector<int>& untold = untold_.Of(id);
  if (untold.empty()) return;
  Record(id, FramesWrittenEvent(untold), recorded);
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
  for (uint64_t id : told) untold_.Clear(id);
  for (const JobEvent& event : recorded) {
    for (const auto& [listenerId, listener] : listeners_) listener(event);
  }
}

}  // namespace tcfarm
