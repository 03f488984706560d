// A worker's HTTP face for operators: GET /metrics (Prometheus text) and GET /healthz
// (200 while the daemon's loop keeps turning, 503 once it has stalled; the body says
// whether the coordinator answers). Served on its own thread, so a scrape never waits
// for a task to finish.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <prometheus/registry.h>

#include "proto/net/http_listener.h"

namespace tcfarm {

struct WorkerHealth {
  bool responsive = false;         // the daemon loop turned recently
  bool coordinatorAnswers = false;
};

class MetricsEndpoint {
 public:
  MetricsEndpoint(std::shared_ptr<prometheus::Registry> registry,
                  std::function<WorkerHealth()> health);
  // Listens on host:port (port 0: any free port); returns the port bound. Throws
  // std::runtime_error when the address cannot be bound.
  int Start(const std::string& host, int port);

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  std::function<WorkerHealth()> health_;
  HttpListener listener_;
};

// Splits "HOST:PORT" (what --metrics takes). Throws std::invalid_argument otherwise.
void ParseListenAddress(const std::string& text, std::string* host, int* port);

}  // namespace tcfarm
