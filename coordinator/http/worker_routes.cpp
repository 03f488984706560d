#include "coordinator/http/worker_routes.h"

#include <httplib.h>

#include "coordinator/http/job_json.h"

namespace tcfarm::http {

std::vector<Route> WorkerRoutes::Routes() {
  return {
      {"GET", "/api/v1/workers", Access::kRead, Bind(this, &WorkerRoutes::ListWorkers)},
      {"DELETE", "/api/v1/workers/distrusted", Access::kAdmin, Bind(this, &WorkerRoutes::LiftWorkerBan)},
  };
}

void WorkerRoutes::ListWorkers(const httplib::Request& request, const std::string&, httplib::Response& response) {
  // ?distrusted: the workers banned for returning wrong values instead of those connected.
  if (request.has_param("distrusted")) {
    WriteJson(response, BansJson(farm_.Bans()));
    return;
  }
  WriteJson(response, WorkersJson(farm_.Snapshot()));
}

void WorkerRoutes::LiftWorkerBan(const httplib::Request& request, const std::string&, httplib::Response& response) {
  // A query parameter, not a path segment: a CURVE key's Z85 text may hold '/' and '?'.
  if (request.get_param_value_count("principal") != 1) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "principal: expected once, as in ?principal=key:<Z85 public key> or ?principal=name:<name>@<address> "
                   "(GET /api/v1/workers?distrusted lists them)");
  }
  const std::string principal = request.get_param_value("principal");
  if (!farm_.LiftBan(principal)) {
    throw ApiError(404, error_code::kBanNotFound, "no worker is banned as " + principal);
  }
  WriteJson(response, nlohmann::json{{"lifted", principal}});
}

}  // namespace tcfarm::http
