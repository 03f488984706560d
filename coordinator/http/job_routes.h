// The HTTP API's jobs: submit, list, read, cancel, retry, change (priority, name) and
// delete. A submit token may cancel, retry, change and delete its own jobs only
// (ApiAuth::CheckMayChange).
//   POST   /api/v1/jobs                submit (http/submit_request.h reads the body)
//   GET    /api/v1/jobs                a page of jobs, filtered
//   GET    /api/v1/jobs/{id}           one job, with its per-frame figures
//   POST   /api/v1/jobs/{id}/cancel    POST /api/v1/jobs/{id}/retry
//   PATCH  /api/v1/jobs/{id}           DELETE /api/v1/jobs/{id}
//   POST   /api/v1/scenes/check        what a submit of the same body would import, nothing
//                                      stored (http/submit_request.h, CheckSubmission)
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/farm/farm_control.h"
#include "coordinator/http/api_route.h"
#include "coordinator/http/frame_routes.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/asset_store.h"
#include "coordinator/store/store_janitor.h"
#include "proto/scene/import/import_budget.h"

namespace prometheus {
class Counter;
class Gauge;
class Registry;
template <typename T>
class Family;
}  // namespace prometheus

namespace tcfarm::http {

// What a submission may need (ApiOptions has their meaning).
struct JobLimits {
  uint64_t farmMemoryBytes = 0;    // 0: no limit
  uint64_t pendingFrameBytes = 0;
  uint64_t assetMaxJobBytes = 0;   // 0: no limit
  ImportBudget* importBudget = nullptr;  // none: no farm-wide bound on imports
};

class JobRoutes {
 public:
  // janitor: deletes jobs, and holds the assets a submission names until it is stored.
  // assets: where a submission's assets must be. ranges: filled at submit, emptied at delete.
  JobRoutes(JobStore& store, FarmControl& farm, StoreJanitor& janitor, AssetStore& assets,
            FrameRanges& ranges, const ApiAuth& auth, JobLimits limits, prometheus::Registry* metrics);
  ~JobRoutes();  // the import budget's gauges are no longer set
  JobRoutes(const JobRoutes&) = delete;
  JobRoutes& operator=(const JobRoutes&) = delete;

  std::vector<Route> Routes();

 private:
  void SubmitJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void CheckJobFitsInMemory(const JobSpec& spec) const;
  // Counts a stored submission's import warnings by code (tcfarm_import_warnings_total).
  void CountImportWarnings(const JobSpec& spec);
  void CheckScene(const httplib::Request& request, const std::string& body, httplib::Response& response);
  // Runs `import` (the whole reading of a check's or a submit's body) within the import
  // budget, holding first what reading the body takes (its document, the scene file it
  // carries). The budget's refusals are answered 503 import_busy with Retry-After, or 413
  // import_too_large when the scene could never fit.
  void Importing(const std::string& body, const std::function<void()>& import);
  void WatchImportBudget(prometheus::Registry& metrics);
  void ListJobs(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void CancelJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void RetryJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void PatchJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void DeleteJob(const httplib::Request& request, const std::string& body, httplib::Response& response);

  // A transition the store refused: throws 409 `code` saying the job's state ("is <already>
  // canceled; <expected>"), or 404 when the job is gone.
  [[noreturn]] void RefuseTransition(uint64_t id, const char* code, const std::string& already,
                                     const std::string& expected) const;
  // The Job object with its per-frame figures, a running job's merged with the farm's.
  nlohmann::json JobDetail(const JobRecord& record);

  JobStore& store_;
  FarmControl& farm_;
  prometheus::Family<prometheus::Counter>* importWarnings_ = nullptr;  // with a metrics registry only
  prometheus::Counter* importRefusals_ = nullptr;                      // with a registry and a budget
  StoreJanitor& janitor_;
  AssetStore& assets_;
  FrameRanges& ranges_;
  const ApiAuth& auth_;
  JobLimits limits_;
};

}  // namespace tcfarm::http
