#include "coordinator/http/job_json.h"

#include <ctime>
#include <cstdio>

#include "coordinator/planner/strategy.h"
#include "coordinator/store/frame_finisher.h"

namespace tcfarm::http {

using nlohmann::json;

json IsoUtcOrNull(int64_t unixMs) {
  if (unixMs <= 0) return nullptr;
  const std::time_t seconds = static_cast<std::time_t>(unixMs / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[64];  // room for any int year the compiler can imagine
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", utc.tm_year + 1900,
                utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec,
                static_cast<int>(unixMs % 1000));
  return text;
}

json StrategiesJson() {
  json names = json::array();
  for (const StrategyNameEntry& entry : kStrategyNames) names.push_back(std::string(entry.name));
  return json{{"strategies", names}, {"default", std::string(StrategyName(kDefaultStrategy))}};
}

json ImportWarningsJson(const std::vector<ImportWarning>& warnings) {
  json list = json::array();
  for (const ImportWarning& warning : warnings) {
    list.push_back({{"code", warning.code}, {"file", warning.file}, {"pointer", warning.pointer},
                    {"message", warning.message}});
  }
  return list;
}

std::string JobPath(uint64_t id) { return "/api/v1/jobs/" + std::to_string(id); }

json JobJson(const JobRecord& record, const json* liveStats) {
  const FrameSize frameSize = record.spec.frameSize;
  const int count = record.FrameCount();
  json stats = record.stats.is_object() ? record.stats : json::object();
  if (liveStats != nullptr && liveStats->is_object()) stats.merge_patch(*liveStats);

  json job{
      {"id", record.id},
      {"name", record.spec.name},
      {"state", ToString(record.state)},
      {"strategy", std::string(StrategyName(record.spec.strategy))},
      {"bin_width", record.spec.binWidth},
      {"tolerance", record.spec.tolerance},
      {"priority", record.spec.priority},
      {"width", frameSize.width},
      {"height", frameSize.height},
      {"frames",
       {{"start", record.spec.firstFrame},
        {"end", record.spec.lastFrame},
        {"count", count},
        {"done", record.framesDone}}},
      {"progress", count > 0 ? static_cast<double>(record.framesDone) / count : 0.0},
      {"pixels_traced", record.tracedPixels},
      {"pixels_copied", record.copiedPixels},
      {"traced_pixel_ratio", record.TracedPixelRatio(frameSize.Pixels())},
      {"submitted_at", IsoUtcOrNull(record.submittedMs)},
      {"started_at", IsoUtcOrNull(record.startedMs)},
      {"finished_at", IsoUtcOrNull(record.finishedMs)},
      {"stats", std::move(stats)},
      {"links",
       {{"self", JobPath(record.id)}, {"frames", JobPath(record.id) + "/frames/{frame}.png"}}},
  };
  // How the job's PNG previews show its linear frames; the EXRs are the values themselves.
  const ViewTransform view = JobPreviewView(record.spec);
  job["view"] = std::string(ViewName(view.view));
  job["exposure"] = view.exposure;
  if (record.state == JobState::kFailed) job["error"] = record.error;
  // The id of the API token that submitted the job (never the token), when it had one.
  const json& options = record.spec.options;
  if (options.is_object() && options.contains("submitted_by")) job["submitted_by"] = options["submitted_by"];
  // What importing the scene file left out (an extension not implemented), when anything.
  if (options.is_object() && options.contains("import_warnings")) job["warnings"] = options["import_warnings"];
  return job;
}

json JobDetailJson(const JobRecord& record, const json* liveStats) {
  json job = JobJson(record, liveStats);
  job["traced_per_frame"] = record.tracedPerFrame;
  return job;
}

json EventJson(const JobEvent& event) {
  json body = event.fields.is_object() ? event.fields : json::object();
  body["seq"] = event.seq;
  body["job"] = event.job;
  body["time"] = IsoUtcOrNull(event.timeMs);
  body["type"] = event.type;
  body["message"] = event.message;
  return body;
}

json WorkersJson(const FarmSnapshot& snapshot) {
  json workers = json::array();
  for (const WorkerSnapshot& worker : snapshot.workers) {
    workers.push_back({{"name", worker.name},
                       {"principal", worker.principal},
                       {"capacity", worker.capacity},
                       {"threads", worker.threads},
                       {"in_flight", worker.inFlight},
                       {"tasks_done", worker.tasksDone},
                       {"pixels_done", worker.pixelsDone},
                       {"trace_seconds", worker.traceSeconds},
                       {"seconds_since_heard", worker.secondsSinceHeard},
                       {"connected_seconds", worker.connectedSeconds}});
  }
  return json{{"workers", std::move(workers)},
              {"queued_tasks", snapshot.queuedTasks},
              {"in_flight_tasks", snapshot.inFlightTasks}};
}

json BansJson(const std::vector<WorkerBan>& bans) {
  json distrusted = json::array();
  for (const WorkerBan& ban : bans) {
    distrusted.push_back({{"principal", ban.principal},
                          {"name", ban.name},
                          {"why", ban.why},
                          {"banned_at", IsoUtcOrNull(ban.bannedMs)}});
  }
  return json{{"distrusted", std::move(distrusted)}};
}

}  // namespace tcfarm::http
