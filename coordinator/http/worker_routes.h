// The HTTP API's workers: those connected, those distrusted, and lifting a ban.
//   GET    /api/v1/workers                          connected workers
//   GET    /api/v1/workers?distrusted               workers banned for wrong values
//   DELETE /api/v1/workers/distrusted?principal=    lift one ban (admin)
#pragma once

#include <string>
#include <vector>

#include "coordinator/farm/farm_control.h"
#include "coordinator/http/api_route.h"

namespace tcfarm::http {

class WorkerRoutes {
 public:
  explicit WorkerRoutes(FarmControl& farm) : farm_(farm) {}

  std::vector<Route> Routes();

 private:
  void ListWorkers(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void LiftWorkerBan(const httplib::Request& request, const std::string& body, httplib::Response& response);

  FarmControl& farm_;
};

}  // namespace tcfarm::http
