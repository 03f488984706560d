#include "coordinator/http/job_routes.h"

#include "coordinator/store/frame_finisher.h"

#include <httplib.h>

#include <algorithm>
#include <optional>
#include <utility>

#include "coordinator/http/job_json.h"
#include "coordinator/http/query_params.h"
#include "coordinator/http/submit_request.h"
#include "coordinator/planner/job_memory.h"
#include "proto/json/strict_json.h"
#include "proto/metrics/metric_builders.h"

namespace tcfarm::http {
namespace {

using nlohmann::json;

constexpr int kDefaultListLimit = 50;
constexpr int kMaxListLimit = 1000;  // one page stays a few hundred KiB of JSON
constexpr int64_t kMaxListOffset = int64_t{1} << 53;

int ParseLimit(const httplib::Request& request) {
  return static_cast<int>(ParseInteger(request, "limit", 1, kMaxListLimit, kDefaultListLimit));
}

}  // namespace

JobRoutes::JobRoutes(JobStore& store, FarmControl& farm, StoreJanitor& janitor, AssetStore& assets,
                     FrameRanges& ranges, const ApiAuth& auth, JobLimits limits, prometheus::Registry* metrics)
    : store_(store), farm_(farm), janitor_(janitor), assets_(assets), ranges_(ranges), auth_(auth), limits_(limits) {
  if (metrics == nullptr) return;
  importWarnings_ = &NewCounterFamily(*metrics, "tcfarm_import_warnings_total",
                                      "Warnings importing submitted scenes gave (a default added, a feature left "
                                      "out), by code.");
  if (limits_.importBudget != nullptr) WatchImportBudget(*metrics);
}

JobRoutes::~JobRoutes() {
  if (limits_.importBudget != nullptr) limits_.importBudget->SetObserver(nullptr);
}

void JobRoutes::WatchImportBudget(prometheus::Registry& metrics) {
  NewGauge(metrics, "tcfarm_import_budget_bytes", "Memory that scene imports and decoding may hold at once "
                                                  "(--import-budget-mib).")
      .Set(static_cast<double>(limits_.importBudget->capacityBytes()));
  prometheus::Gauge& reserved = NewGauge(metrics, "tcfarm_import_reserved_bytes",
                                         "Memory the scene imports running now hold of the import budget.");
  prometheus::Gauge& peak = NewGauge(metrics, "tcfarm_import_reserved_peak_bytes",
                                     "The most memory scene imports have held of the import budget at once.");
  importRefusals_ = &NewCounter(metrics, "tcfarm_import_refusals_total",
                                "Scene checks and submits answered 503 import_busy: the import budget stayed in "
                                "use by other imports.");
  limits_.importBudget->SetObserver([&reserved, &peak](const ImportBudgetStats& stats) {
    reserved.Set(static_cast<double>(stats.reservedBytes));
    peak.Set(static_cast<double>(stats.peakReservedBytes));
  });
}

void JobRoutes::Importing(const std::string& body, const std::function<void()>& import) {
  try {
    // The body's document, and as much again for what it carries: a scene file's bytes
    // decoded from base64, an inline scene written out for the scene parser.
    WithinImportBudget(limits_.importBudget, JsonDomBytes(body) + body.size(), import);
  } catch (const ImportBudgetBusyError& error) {
    if (importRefusals_ != nullptr) importRefusals_->Increment();
    throw ApiError(503, error_code::kImportBusy,
                   std::string(error.what()) + "; expected the same request again in " +
                       std::to_string(error.retryAfter().count()) + " s (Retry-After), once they have ended")
        .RetryAfter(error.retryAfter());
  } catch (const ImportTooLargeError& error) {
    throw ApiError(413, error_code::kImportTooLarge,
                   std::string(error.what()) + " (--import-budget-mib " +
                       std::to_string(limits_.importBudget->capacityBytes() >> 20) +
                       "); expected a smaller scene, or a coordinator with a larger --import-budget-mib");
  }
}

std::vector<Route> JobRoutes::Routes() {
  return {
      {"POST", "/api/v1/jobs", Access::kSubmit, Bind(this, &JobRoutes::SubmitJob)},
      {"GET", "/api/v1/jobs", Access::kRead, Bind(this, &JobRoutes::ListJobs)},
      {"GET", "/api/v1/jobs/([^/]+)", Access::kRead, Bind(this, &JobRoutes::GetJob)},
      // A submit token may cancel, retry, change and delete its own jobs only: the
      // handlers check whose the job is (CheckMayChange).
      {"POST", "/api/v1/jobs/([^/]+)/cancel", Access::kSubmit, Bind(this, &JobRoutes::CancelJob)},
      {"POST", "/api/v1/jobs/([^/]+)/retry", Access::kSubmit, Bind(this, &JobRoutes::RetryJob)},
      {"PATCH", "/api/v1/jobs/([^/]+)", Access::kSubmit, Bind(this, &JobRoutes::PatchJob)},
      {"DELETE", "/api/v1/jobs/([^/]+)", Access::kSubmit, Bind(this, &JobRoutes::DeleteJob)},
      {"POST", "/api/v1/scenes/check", Access::kSubmit, Bind(this, &JobRoutes::CheckScene)},
  };
}

// The job's memory at its most, alone and one bin at a time, against the farm's memory for
// all running jobs (RequestedJobShape: the most the strategy the farm resolves may need).
// A job that fits waits in the queue until the running jobs leave it room.
void JobRoutes::CheckJobFitsInMemory(const JobSpec& spec) const {
  if (limits_.farmMemoryBytes == 0) return;
  const JobMemoryShape shape =
      RequestedJobShape(spec.strategy, spec.binWidth, spec.lastFrame - spec.firstFrame + 1, spec.cameraOrLightsChange,
                        spec.frameSize.width, spec.frameSize.height, limits_.pendingFrameBytes);
  const std::string shortfall = MemoryShortfall(limits_.farmMemoryBytes, shape);
  if (!shortfall.empty()) {
    throw ApiError(413, error_code::kJobTooLarge,
                   shortfall + "; expected fewer pixels a frame, a narrower bin_width or a coordinator with "
                               "more memory",
                   "/scene/render");
  }
}

void JobRoutes::SubmitJob(const httplib::Request& request, const std::string& body, httplib::Response& response) {
  // From checking the assets to storing the job that names them, no deletion removes them.
  uint64_t id = 0;
  JobSpec spec;
  Importing(body, [&] {
    const auto holdAssets = janitor_.HoldAssets();
    spec = ParseSubmission(body, SubmissionAssets{&assets_, limits_.assetMaxJobBytes, "--asset-max-job-mib"});
    CheckJobFitsInMemory(spec);
    // Which token submitted the job, by its id (never the token): a submit token may change
    // only its own jobs.
    if (const std::optional<Caller> caller = auth_.CallerOf(request)) spec.options["submitted_by"] = caller->tokenId;
    id = store_.Submit(spec);
  });
  CountImportWarnings(spec);
  ranges_.Remember(id, FrameRanges::Range{spec.firstFrame, spec.lastFrame, JobPreviewView(spec)});
  response.set_header("Location", JobPath(id));
  WriteJson(response, JobDetail(LoadJob(store_, id)), 201);
}

void JobRoutes::CountImportWarnings(const JobSpec& spec) {
  if (importWarnings_ == nullptr || !spec.options.contains("import_warnings")) return;
  for (const json& warning : spec.options["import_warnings"]) {
    importWarnings_->Add({{"code", warning.at("code").get<std::string>()}}).Increment();
  }
}

// A submission's dry run: its scene imported as the submit would, its bad input refused
// with the same 400, nothing stored and no job made.
void JobRoutes::CheckScene(const httplib::Request&, const std::string& body, httplib::Response& response) {
  SceneCheck check;
  Importing(body, [&] {
    // The assets it names stay while they are laid out, as a submission's do.
    const auto holdAssets = janitor_.HoldAssets();
    check = CheckSubmission(body, SubmissionAssets{&assets_, limits_.assetMaxJobBytes, "--asset-max-job-mib"});
  });
  json answer{{"ok", true}, {"complete", check.complete}, {"warnings", check.warnings}};
  if (check.complete) {
    answer["frames"] = {{"start", check.firstFrame}, {"end", check.lastFrame}};
    answer["width"] = check.width;
    answer["height"] = check.height;
  } else {
    answer["missing_assets"] = check.missingAssets;
  }
  WriteJson(response, answer);
}

void JobRoutes::ListJobs(const httplib::Request& request, const std::string&, httplib::Response& response) {
  JobQuery query;
  query.states = ParseStateFilter(request);
  query.strategies = ParseStrategyFilter(request);
  query.nameContains = ParseNameFilter(request);
  query.limit = ParseLimit(request);
  query.offset = ParseInteger(request, "offset", 0, kMaxListOffset, 0);
  const JobPage page = store_.Query(query);
  const std::vector<JobRecord>& records = page.records;
  const bool anyRunning = std::any_of(records.begin(), records.end(), [](const JobRecord& record) {
    return record.state == JobState::kRunning;
  });
  const FarmSnapshot snapshot = anyRunning ? farm_.Snapshot() : FarmSnapshot{};
  json jobs = json::array();
  for (const JobRecord& record : records) {
    const auto live = snapshot.runningStats.find(record.id);
    jobs.push_back(JobJson(record, live == snapshot.runningStats.end() ? nullptr : &live->second));
  }
  WriteJson(response,
            json{{"jobs", std::move(jobs)}, {"total", page.total}, {"offset", query.offset}, {"limit", query.limit}});
}

void JobRoutes::GetJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  WriteJson(response, JobDetail(LoadJob(store_, ParseJobId(request.matches[1]))));
}

void JobRoutes::CancelJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  auth_.CheckMayChange(request, store_, id);
  // Cancel first and ask afterwards: checking the state first would race with the farm
  // finishing the job in between.
  if (!store_.Cancel(id)) {
    RefuseTransition(id, error_code::kJobFinished, "already ", "only queued or running jobs can be canceled");
  }
  farm_.RequestCancel(id);
  WriteJson(response, JobDetail(LoadJob(store_, id)));
}

void JobRoutes::RefuseTransition(uint64_t id, const char* code, const std::string& already,
                                 const std::string& expected) const {
  throw ApiError(409, code,
                 "job " + std::to_string(id) + " is " + already + ToString(RequireJob(store_, id)) + "; " + expected);
}

void JobRoutes::RetryJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  auth_.CheckMayChange(request, store_, id);
  if (!store_.Retry(id)) RefuseTransition(id, error_code::kJobNotRetryable, "", "only failed or canceled jobs can be retried");
  WriteJson(response, JobDetail(LoadJob(store_, id)));
}

void JobRoutes::PatchJob(const httplib::Request& request, const std::string& body, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const JobChange change = ParseJobChange(body);
  auth_.CheckMayChange(request, store_, id);
  if (!store_.Change(id, change)) RequireJob(store_, id);
  // A running job's next tasks follow it; a queued one is claimed by it from the store.
  if (change.priority) farm_.RequestPriority(id, *change.priority);
  WriteJson(response, JobDetail(LoadJob(store_, id)));
}

void JobRoutes::DeleteJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  auth_.CheckMayChange(request, store_, id);
  StoreJanitor::Deletion deletion;
  try {
    deletion = janitor_.Delete(id, "on request (DELETE)");
  } catch (const FarmStoppingError& e) {
    throw ApiError(503, error_code::kShuttingDown, std::string(e.what()) + "; expected it to be asked again once the coordinator runs");
  }
  switch (deletion.outcome) {
    case DeletedJob::Outcome::kNotFound:
      throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
    case DeletedJob::Outcome::kActive:
      throw ApiError(409, error_code::kJobActive,
                     "job " + std::to_string(id) + " is " + ToString(deletion.state) +
                         "; cancel it first (POST /api/v1/jobs/" + std::to_string(id) + "/cancel), then delete it");
    case DeletedJob::Outcome::kDeleted:
      break;
  }
  ranges_.Forget(id);
  WriteJson(response, json{{"deleted", id}, {"freed_bytes", deletion.freedBytes}});
}

json JobRoutes::JobDetail(const JobRecord& record) {
  if (record.state != JobState::kRunning) return JobDetailJson(record, nullptr);
  const FarmSnapshot snapshot = farm_.Snapshot();
  const auto live = snapshot.runningStats.find(record.id);
  return JobDetailJson(record, live == snapshot.runningStats.end() ? nullptr : &live->second);
}

}  // namespace tcfarm::http
