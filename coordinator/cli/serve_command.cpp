#include "cli/serve_command.h"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>

#include "farm/farm.h"
#include "frame/frame_io.h"
#include "farm/local_workers.h"
#include "farm/machine_memory.h"
#include "http/api_server.h"
#include "jobs/job_store.h"

namespace tcfarm {
namespace {

constexpr const char* kUsage =
    "usage: tcfarm-coordinator serve [--http HOST:PORT] [--zmq ENDPOINT] [--store DIR] "
    "[--db FILE]\n"
    "           [--local-workers N] [--worker-threads T] [--worker-binary PATH] "
    "[--max-running-jobs K]\n"
    "           [--exr-compression zip[:1-9]|none|rle|zips|piz] [--writer-threads N] "
    "[--dashboard DIR]\n"
    "           [--pending-frame-memory MIB]   per job, frames finished ahead of their turn; "
    "beyond it they wait on disk (default 256)\n"
    "           [--job-memory MIB]   per job, the frames it holds at once; larger jobs are refused "
    "(default: half the memory it may use)\n"
    "           [--worker-timeout MS]   silence after which a worker's tasks are requeued (default 5000)\n"
    "defaults: --http 127.0.0.1:8080 --zmq tcp://*:5555 --store store --db store/jobs.db "
    "--local-workers 1\n"
    "          --dashboard: services/dashboard of the source tree the binary was built in, "
    "when there\n"
    "(--local-workers 0 for a coordinator whose workers run elsewhere)\n";

struct ServeOptions {
  std::string httpHost = "127.0.0.1";
  int httpPort = 8080;
  FarmOptions farm;
  std::filesystem::path database;
  unsigned localWorkers = 1;  // the embedded local farm: one worker using all cores
  unsigned workerThreads = 0;
  std::string workerBinary;
  std::filesystem::path dashboard;  // static files served at /; empty: none
};

// The dashboard beside a build tree (build/coordinator -> ../../services/dashboard) or
// an installed one (bin -> ../share/tcfarm/dashboard); empty when neither is there.
std::filesystem::path FindDashboard() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const std::filesystem::path folder = self.parent_path();
  for (const auto& candidate : {folder.parent_path().parent_path() / "services" / "dashboard",
                                folder.parent_path() / "share" / "tcfarm" / "dashboard"}) {
    if (std::filesystem::is_regular_file(candidate / "index.html", ec)) return candidate;
  }
  return {};
}

std::atomic<bool> stopRequested{false};
void RequestStop(int) { stopRequested = true; }

int ParseInt(const std::string& text, const std::string& flag, int minimum, int maximum) {
  size_t used = 0;
  long value = minimum - 1L;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
  }
  if (used != text.size() || value < minimum || value > maximum) {
    throw std::invalid_argument(flag + " " + text + ": expected an integer from " +
                                std::to_string(minimum) + " to " + std::to_string(maximum));
  }
  return static_cast<int>(value);
}

void ParseHttpAddress(const std::string& text, ServeOptions* options) {
  size_t colon = text.rfind(':');
  if (colon == std::string::npos) throw std::invalid_argument("--http " + text + ": expected HOST:PORT");
  options->httpHost = text.substr(0, colon);
  options->httpPort = ParseInt(text.substr(colon + 1), "--http port", 0, 65535);
}

// A job's default share of the memory this process may use (its container's limit
// included): other jobs, workers on this machine and the system need the rest.
uint64_t HalfTheUsableMemory() {
  return UsableMemoryBytes().value_or(uint64_t{16} << 30) / 2;  // unknown: assume 16 GiB
}

ServeOptions ParseServeOptions(const std::vector<std::string>& args) {
  ServeOptions options;
  options.dashboard = FindDashboard();
  for (size_t i = 0; i < args.size(); ++i) {
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw std::invalid_argument(args[i] + " needs a value");
      return args[++i];
    };
    const std::string& flag = args[i];
    if (flag == "--http") ParseHttpAddress(value(), &options);
    else if (flag == "--zmq") options.farm.endpoint = value();
    else if (flag == "--store") options.farm.storeRoot = value();
    else if (flag == "--db") options.database = value();
    else if (flag == "--local-workers") options.localWorkers = ParseInt(value(), flag, 0, 256);
    else if (flag == "--worker-threads") options.workerThreads = ParseInt(value(), flag, 0, 4096);
    else if (flag == "--worker-binary") options.workerBinary = value();
    else if (flag == "--max-running-jobs") options.farm.maxRunningJobs = ParseInt(value(), flag, 1, 1024);
    else if (flag == "--exr-compression") options.farm.output.exrCompression = value();
    else if (flag == "--writer-threads") options.farm.output.threads = ParseInt(value(), flag, 1, 64);
    else if (flag == "--dashboard") options.dashboard = value();
    else if (flag == "--worker-timeout")
      options.farm.heartbeat.SetTimeout(Milliseconds(ParseInt(value(), flag, 100, 3600000)));
    else if (flag == "--job-memory")
      options.farm.jobMemoryBytes = static_cast<uint64_t>(ParseInt(value(), flag, 1, 1 << 30)) << 20;
    else if (flag == "--pending-frame-memory")
      options.farm.pendingFrameBytes = static_cast<size_t>(ParseInt(value(), flag, 0, 1 << 20)) << 20;
    else throw std::invalid_argument("unexpected argument " + flag);
  }
  if (!options.dashboard.empty() && !std::filesystem::is_directory(options.dashboard)) {
    throw std::invalid_argument("--dashboard " + options.dashboard.string() + ": not a folder");
  }
  if (options.database.empty()) options.database = options.farm.storeRoot / "jobs.db";
  if (options.farm.jobMemoryBytes == 0) options.farm.jobMemoryBytes = HalfTheUsableMemory();
  if (!IsLosslessExrCompression(options.farm.output.exrCompression)) {
    throw std::invalid_argument("--exr-compression " + options.farm.output.exrCompression +
                                ": expected a lossless one: none, rle, zips, zip or piz");
  }
  return options;
}

// Where local workers connect: a wildcard bind is reached through loopback.
std::string LoopbackEndpoint(std::string bound) {
  for (const char* any : {"0.0.0.0", "[::]", "*"}) {
    size_t at = bound.find(any);
    if (at != std::string::npos) bound.replace(at, std::string(any).size(), "127.0.0.1");
  }
  return bound;
}

}  // namespace

int RunServe(const std::vector<std::string>& args) {
  ServeOptions options;
  try {
    options = ParseServeOptions(args);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tcfarm-coordinator serve: %s\n%s", e.what(), kUsage);
    return 2;
  }
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  std::signal(SIGPIPE, SIG_IGN);

  std::filesystem::create_directories(options.farm.storeRoot);
  if (options.database.has_parent_path()) {
    std::filesystem::create_directories(options.database.parent_path());
  }
  JobStore store(options.database);
  SystemClock clock;
  Farm farm(store, options.farm, clock);

  ApiOptions api;
  api.host = options.httpHost;
  api.port = options.httpPort;
  api.storeRoot = options.farm.storeRoot;
  api.dashboardDirectory = options.dashboard;
  api.jobMemoryBytes = options.farm.jobMemoryBytes;
  ApiServer server(store, farm, farm.metrics().registry, api);
  int port = server.Start();

  std::string workerEndpoint = LoopbackEndpoint(farm.BoundEndpoint());
  LocalWorkers localWorkers(options.workerBinary.empty() ? FindWorkerBinary() : options.workerBinary,
                            workerEndpoint, options.workerThreads);
  localWorkers.Start(options.localWorkers);

  std::printf("tcfarm-coordinator: listening http=http://%s:%d zmq=%s workers=%u store=%s\n",
              options.httpHost.c_str(), port, workerEndpoint.c_str(), options.localWorkers,
              options.farm.storeRoot.c_str());
  std::fflush(stdout);
  if (!options.dashboard.empty()) {
    std::fprintf(stderr, "tcfarm-coordinator: dashboard at http://%s:%d/ from %s\n",
                 options.httpHost.c_str(), port, options.dashboard.c_str());
  }

  // Run the farm; look after the local workers a few times a second. On SIGINT or SIGTERM
  // it tells its workers goodbye before it returns.
  auto lastCheck = clock.Now();
  farm.Run(stopRequested, [&] {
    if (clock.Now() - lastCheck > Milliseconds(250)) {
      localWorkers.RestartExited();
      lastCheck = clock.Now();
    }
  });
  std::fprintf(stderr, "tcfarm-coordinator: stopping\n");
  server.Stop();
  localWorkers.Stop();
  return 0;
}

}  // namespace tcfarm
