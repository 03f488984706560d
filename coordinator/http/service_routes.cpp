#include "coordinator/http/service_routes.h"

#include <httplib.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>

#include "coordinator/http/job_json.h"

namespace tcfarm::http {
namespace {

// The Prometheus text exposition format, version 0.0.4: what a scraper asks for.
constexpr const char* kMetricsType = "text/plain; version=0.0.4";

}  // namespace

std::vector<Route> ServiceRoutes::Routes() {
  return {
      {"GET", "/api/v1/strategies", Access::kRead, Bind(this, &ServiceRoutes::ListStrategies)},
      // Liveness probes (Kubernetes, compose) carry no token; the answer holds no data.
      {"GET", "/healthz", Access::kOpen, Bind(this, &ServiceRoutes::Health)},
      {"GET", "/metrics", Access::kRead, Bind(this, &ServiceRoutes::Metrics)},
  };
}

void ServiceRoutes::ListStrategies(const httplib::Request&, const std::string&, httplib::Response& response) {
  WriteJson(response, StrategiesJson());
}

void ServiceRoutes::Health(const httplib::Request&, const std::string&, httplib::Response& response) {
  WriteJson(response, nlohmann::json{{"status", "ok"}});
}

void ServiceRoutes::Metrics(const httplib::Request&, const std::string&, httplib::Response& response) {
  const std::string text = metrics_ ? prometheus::TextSerializer().Serialize(metrics_->Collect()) : "";
  response.set_content(text, kMetricsType);
}

}  // namespace tcfarm::http
