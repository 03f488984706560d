// tcfarm-worker: a stateless tracing process.
//   tcfarm-worker serve [--coordinator tcp://HOST:5555] [--threads N] ...   trace tasks
//   tcfarm-worker render SCENE [--frames A:B] [--out DIR] ...   brute-force reference render
//                                                 (runs tcfarm-render, installed beside it)
//   tcfarm-worker keygen --name NAME [--out DIR]   a CURVE key pair for the coordinator link
// Each answers --help with its flags.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <optional>
#include <stdexcept>
#include <string>

#include "proto/command_line/command_line.h"
#include "proto/curve/curve_keys.h"
#include "proto/curve/keygen_command.h"
#include "worker/daemon/worker_daemon.h"

namespace {

std::atomic<bool> stopRequested{false};

void RequestStop(int) { stopRequested = true; }

struct ServeArguments {
  tcfarm::WorkerOptions worker;
  std::string metricsAddress;  // empty: no HTTP endpoint
  long coordinatorTimeoutMs = tcfarm::HeartbeatPolicy{}.timeout.count();
  std::string assetCache;
  uint64_t assetMaxMib = tcfarm::WorkerOptions{}.maxAssetBytes >> 20;
  CLI::Option* coordinatorTimeoutOption = nullptr;  // set when given
  std::string curveSecret;     // empty: no CURVE
  std::string coordinatorKey;
};

void AddServeFlags(CLI::App& serve, ServeArguments& parsed) {
  using tcfarm::cli::IntegerFrom;
  tcfarm::WorkerOptions& options = parsed.worker;
  serve.add_option("--coordinator", options.coordinator, "The coordinator's ZeroMQ endpoint")
      ->type_name("tcp://HOST:PORT")
      ->envname("TCFARM_COORDINATOR")
      ->capture_default_str();
  serve.add_option("--threads", options.threads, "Tracing threads (0: one per core)")
      ->type_name("N")
      ->check(IntegerFrom(0, 65536))
      ->capture_default_str();
  serve.add_option("--capacity", options.capacity,
                   "Tasks in flight: one tracing, the rest queued here (at most " +
                       std::to_string(tcfarm::wire::kMaxCapacity) + ")")
      ->type_name("K")
      ->check(IntegerFrom(1, 65536))
      ->capture_default_str();
  serve.add_option("--name", options.name,
                   "Name in the coordinator's worker list (default: HOST:PID)")
      ->type_name("NAME");
  serve.add_option("--metrics", parsed.metricsAddress,
                   "Serve /metrics and /healthz over HTTP at this address (default: not at all)")
      ->type_name("HOST:PORT")
      ->envname("TCFARM_WORKER_METRICS");
  serve.add_option("--asset-cache", parsed.assetCache,
                   "Folder of assets (texture images) fetched from the coordinator, by hash; several workers "
                   "may share one (default: tcfarm-assets-UID in the temp directory)")
      ->type_name("DIR")
      ->envname("TCFARM_ASSET_CACHE");
  serve.add_option("--asset-max-mib", parsed.assetMaxMib, "Largest asset this worker fetches")
      ->type_name("MIB")
      ->check(IntegerFrom(1, 1 << 20))
      ->capture_default_str();
  parsed.coordinatorTimeoutOption =
      serve.add_option("--coordinator-timeout", parsed.coordinatorTimeoutMs,
                       "Silence after which the coordinator is taken for gone and reconnected to")
          ->type_name("MS")
          ->check(IntegerFrom(100, 65536))
          ->capture_default_str();
  serve.add_option("--curve-secret", parsed.curveSecret,
                   "This worker's CURVE secret key (tcfarm-worker keygen); its .pub must be in the "
                   "coordinator's --worker-keys folder. Needs --coordinator-key")
      ->type_name("FILE")
      ->envname("TCFARM_CURVE_SECRET");
  serve.add_option("--coordinator-key", parsed.coordinatorKey,
                   "The coordinator's CURVE public key (its .pub file): the worker talks only to it")
      ->type_name("FILE")
      ->envname("TCFARM_COORDINATOR_KEY");
}

// Both key files or neither; a file that is not a key names itself.
std::optional<tcfarm::CurveClientKeys> ReadCurveKeys(const ServeArguments& parsed) {
  if (parsed.curveSecret.empty() != parsed.coordinatorKey.empty()) {
    throw std::invalid_argument(std::string(parsed.curveSecret.empty() ? "--coordinator-key" : "--curve-secret") +
                                " without " + (parsed.curveSecret.empty() ? "--curve-secret" : "--coordinator-key") +
                                ": CURVE needs this worker's secret key and the coordinator's public key");
  }
  if (parsed.curveSecret.empty()) return std::nullopt;
  tcfarm::CurveClientKeys keys;
  try {
    const tcfarm::curve::KeyPair own = tcfarm::curve::ReadSecretKeyFile(parsed.curveSecret);
    keys.secretKey = own.secretKey;
    keys.publicKey = own.publicKey;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--curve-secret ") + e.what());
  }
  try {
    keys.coordinatorKey = tcfarm::curve::ReadKeyFile(parsed.coordinatorKey);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--coordinator-key ") + e.what());
  }
  return keys;
}

int RunServe(ServeArguments parsed) {
  parsed.worker.capacity = std::min(parsed.worker.capacity, tcfarm::wire::kMaxCapacity);
  parsed.worker.assetCache = parsed.assetCache;
  parsed.worker.maxAssetBytes = parsed.assetMaxMib << 20;
  parsed.worker.curve = ReadCurveKeys(parsed);
  if (parsed.coordinatorTimeoutOption->count()) {
    parsed.worker.heartbeat.SetTimeout(tcfarm::Milliseconds(parsed.coordinatorTimeoutMs));
  }
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
  if (parsed.worker.curve) {
    std::fprintf(stderr, "tcfarm-worker: CURVE public key %s\n", parsed.worker.curve->publicKey.c_str());
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
  // tcfarm-render parses its own command line, --help included.
  if (argc >= 2 && std::strcmp(argv[1], "render") == 0) return ExecRender(argv + 1);
  CLI::App program("A stateless tracing process: traces the tasks a coordinator sends it.",
                   "tcfarm-worker");
  tcfarm::cli::SetUpProgram(program);
  program.require_subcommand(1);
  CLI::App* serve = program.add_subcommand("serve", "Trace tasks for a coordinator until stopped");
  ServeArguments parsed;
  AddServeFlags(*serve, parsed);
  program.add_subcommand("render",
                         "Brute-force reference render of a scene's frames (runs tcfarm-render, "
                         "installed beside this program; see tcfarm-worker render --help)");
  const tcfarm::cli::Subcommand keygen = tcfarm::curve::AddKeygenCommand(program);
  if (auto exitCode = tcfarm::cli::ParseCommandLine(program, argc, argv)) return *exitCode;
  if (keygen.app->parsed()) return keygen.run();
  try {
    return RunServe(parsed);
  } catch (const std::invalid_argument& e) {  // a flag's value that cannot be used
    return tcfarm::cli::ReportUsageError(program, e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-worker serve: %s\n", e.what());
    return 1;
  }
}
