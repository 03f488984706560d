// tcfarm-worker: a stateless tracing process.
//   tcfarm-worker serve [--coordinator tcp://HOST:5555] [--threads N] [--capacity K] [--name NAME]
//                       [--metrics HOST:PORT]   serve /metrics and /healthz over HTTP
//   tcfarm-worker render SCENE --frames A:B --out DIR   brute-force reference render
//                                                       (runs tcfarm-render, installed beside it)
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <exception>
#include <string>
#include <algorithm>
#include <vector>

#include "daemon/worker_daemon.h"

namespace {

constexpr const char* kUsage =
    "usage: tcfarm-worker serve [--coordinator tcp://HOST:PORT] [--threads N] [--capacity K] "
    "[--name NAME]\n"
    "                           [--metrics HOST:PORT] [--coordinator-timeout MS]\n"
    "       tcfarm-worker render SCENE (.json or .obj) [--frames A:B] [--out DIR] [--threads N]\n";

std::atomic<bool> stopRequested{false};

void RequestStop(int) { stopRequested = true; }

unsigned ParseCount(const std::string& text, const std::string& flag, unsigned minimum) {
  size_t used = 0;
  long value = -1;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
  }
  if (used != text.size() || value < static_cast<long>(minimum) || value > 65536) {
    throw std::invalid_argument(flag + " " + text + ": expected an integer from " +
                                std::to_string(minimum) + " to 65536");
  }
  return static_cast<unsigned>(value);
}

struct ServeArguments {
  tcfarm::WorkerOptions worker;
  std::string metricsAddress;  // empty: no HTTP endpoint
};

ServeArguments ParseServeArguments(const std::vector<std::string>& args) {
  ServeArguments parsed;
  tcfarm::WorkerOptions& options = parsed.worker;
  if (const char* env = std::getenv("TCFARM_COORDINATOR")) options.coordinator = env;
  if (const char* env = std::getenv("TCFARM_WORKER_METRICS")) parsed.metricsAddress = env;
  for (size_t i = 0; i < args.size(); ++i) {
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw std::invalid_argument(args[i] + " needs a value");
      return args[++i];
    };
    if (args[i] == "--coordinator") {
      options.coordinator = value();
    } else if (args[i] == "--threads") {
      options.threads = ParseCount(value(), "--threads", 0);
    } else if (args[i] == "--capacity") {
      options.capacity = std::min(ParseCount(value(), "--capacity", 1), tcfarm::wire::kMaxCapacity);
    } else if (args[i] == "--name") {
      options.name = value();
    } else if (args[i] == "--metrics") {
      parsed.metricsAddress = value();
    } else if (args[i] == "--coordinator-timeout") {
      // Silence after which the coordinator is taken for gone and reconnected to.
      options.heartbeat.SetTimeout(tcfarm::Milliseconds(ParseCount(value(), "--coordinator-timeout", 100)));
    } else {
      throw std::invalid_argument("unexpected argument " + args[i]);
    }
  }
  return parsed;
}

int RunServe(const std::vector<std::string>& args) {
  const ServeArguments parsed = ParseServeArguments(args);
  std::string metricsHost;
  int metricsPort = 0;
  if (!parsed.metricsAddress.empty()) {
    tcfarm::ParseListenAddress(parsed.metricsAddress, &metricsHost, &metricsPort);
  }
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  tcfarm::SystemClock clock;
  tcfarm::WorkerDaemon daemon(parsed.worker, clock);
  tcfarm::MetricsEndpoint endpoint(daemon.metrics().registry, [&daemon] { return daemon.Health(); });
  if (!parsed.metricsAddress.empty()) {
    const int port = endpoint.Start(metricsHost, metricsPort);
    std::fprintf(stderr, "tcfarm-worker: metrics on http://%s:%d/metrics\n", metricsHost.c_str(), port);
  }
  std::fprintf(stderr, "tcfarm-worker: serving %s\n", parsed.worker.coordinator.c_str());
  daemon.Run(stopRequested);
  return 0;
}

// Replaces this process with tcfarm-render from the same folder (or PATH).
int ExecRender(char** argv) {
  char self[4096];
  ssize_t length = readlink("/proc/self/exe", self, sizeof self - 1);
  std::string beside;
  if (length > 0) {
    self[length] = 0;
    beside = std::string(self);
    beside = beside.substr(0, beside.rfind('/') + 1) + "tcfarm-render";
  }
  argv[0] = const_cast<char*>("tcfarm-render");
  if (!beside.empty()) execv(beside.c_str(), argv);
  execvp("tcfarm-render", argv);
  std::perror("tcfarm-worker render: cannot run tcfarm-render");
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  const std::string command = args[0];
  args.erase(args.begin());
  try {
    if (command == "serve") return RunServe(args);
    if (command == "render") return ExecRender(argv + 1);
    std::fprintf(stderr, "tcfarm-worker: unknown command '%s'\n%s", command.c_str(), kUsage);
    return 2;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tcfarm-worker %s: %s\n", command.c_str(), e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-worker %s: %s\n", command.c_str(), e.what());
    return 1;
  }
}
