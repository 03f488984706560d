#include "worker/daemon/metrics_endpoint.h"

#include <stdexcept>

#include <prometheus/text_serializer.h>

namespace tcfarm {

MetricsEndpoint::MetricsEndpoint(std::shared_ptr<prometheus::Registry> registry,
                                 std::function<WorkerHealth()> health)
    : registry_(std::move(registry)), health_(std::move(health)) {}

int MetricsEndpoint::Start(const std::string& host, int port) {
  auto server = std::make_unique<GuardedServer>();  // GETs only: every request body is refused
  server->Get("/metrics", [this](const httplib::Request&, httplib::Response& response) {
    response.set_content(prometheus::TextSerializer().Serialize(registry_->Collect()),
                         "text/plain; version=0.0.4; charset=utf-8");
  });
  server->Get("/healthz", [this](const httplib::Request&, httplib::Response& response) {
    const WorkerHealth health = health_();
    response.status = health.responsive ? 200 : 503;
    response.set_content(std::string("{\"status\":\"") + (health.responsive ? "ok" : "stalled") +
                             "\",\"coordinator\":\"" +
                             (health.coordinatorAnswers ? "connected" : "unreachable") + "\"}\n",
                         "application/json");
  });
  return listener_.Start(std::move(server), host, port);
}

void ParseListenAddress(const std::string& text, std::string* host, int* port) {
  const size_t colon = text.rfind(':');
  size_t used = 0;
  long value = -1;
  if (colon != std::string::npos && colon + 1 < text.size()) {
    try {
      value = std::stol(text.substr(colon + 1), &used);
    } catch (const std::exception&) {
    }
  }
  if (colon == std::string::npos || colon == 0 || used != text.size() - colon - 1 || value < 0 ||
      value > 65535) {
    throw std::invalid_argument("--metrics " + text + ": expected HOST:PORT with a port from 0 to 65535");
  }
  *host = text.substr(0, colon);
  *port = static_cast<int>(value);
}

}  // namespace tcfarm
