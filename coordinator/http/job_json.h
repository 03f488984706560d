// How records and snapshots look on the wire (proto/openapi.yaml: Job, Worker).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/farm_control.h"
#include "coordinator/jobs/job_store.h"
#include "proto/scene/scene.h"

namespace tcfarm::http {

// "2024-05-01T12:34:56.789Z"; null for 0 (the store's "not yet").
nlohmann::json IsoUtcOrNull(int64_t unixMs);

// The Job object. liveStats (a running job's figures from the farm, may be null) is
// merge-patched over record.stats, since the store's copy is only refreshed now and then.
// traced_pixel_ratio always counts finished frames only (JobRecord::TracedPixelRatio):
// live while running, and over all frames once frames.done == frames.count.
nlohmann::json JobJson(const JobRecord& record, const nlohmann::json* liveStats);
// JobJson plus "traced_per_frame" (-1 for frames not finished), for a record from
// JobStore::Get; lists leave it out, as JobStore::List does, to stay cheap.
nlohmann::json JobDetailJson(const JobRecord& record, const nlohmann::json* liveStats);

// An event: {"seq", "job", "time", "type", "message"} and its own fields beside them.
nlohmann::json EventJson(const JobEvent& event);

// GET /api/v1/workers body.
nlohmann::json WorkersJson(const FarmSnapshot& snapshot);
// GET /api/v1/workers?distrusted: {"distrusted": [{principal, name, why, banned_at}]}.
nlohmann::json BansJson(const std::vector<WorkerBan>& bans);

// GET /api/v1/strategies: {"strategies": [names, in kStrategyNames's order], "default"}, so
// clients offer the coordinator's own list instead of a copy of it.
nlohmann::json StrategiesJson();

// A scene's import warnings as the job record and the scene check show them: each
// {"code", "file", "pointer", "message"}.
nlohmann::json ImportWarningsJson(const std::vector<ImportWarning>& warnings);

std::string JobPath(uint64_t id);  // "/api/v1/jobs/<id>"

}  // namespace tcfarm::http
