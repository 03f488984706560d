// The HTTP API's routes about the coordinator itself rather than its jobs or workers.
//   GET /api/v1/strategies   the strategies a submission may name, and the default
//   GET /healthz             liveness, open to all (probes carry no token)
//   GET /metrics             Prometheus text exposition (a read token)
// The dashboard's static files at / are the server's mount point (ApiOptions::dashboardDirectory).
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "coordinator/http/api_route.h"

namespace tcfarm::http {

class ServiceRoutes {
 public:
  // metrics: what /metrics serves; null serves an empty page.
  explicit ServiceRoutes(std::shared_ptr<prometheus::Registry> metrics) : metrics_(std::move(metrics)) {}

  std::vector<Route> Routes();

 private:
  void ListStrategies(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void Health(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void Metrics(const httplib::Request& request, const std::string& body, httplib::Response& response);

  std::shared_ptr<prometheus::Registry> metrics_;
};

}  // namespace tcfarm::http
