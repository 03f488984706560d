#include "coordinator/cli/serve_command.h"

#include <malloc.h>
#include <stdlib.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <fstream>
#include <stdexcept>

#include <arpa/inet.h>

#include "proto/curve/curve_keys.h"
#include "coordinator/farm/farm.h"
#include "coordinator/farm/job_run.h"
#include "proto/frame/frame_io.h"
#include "coordinator/farm/local_workers.h"
#include "coordinator/farm/machine_memory.h"
#include "coordinator/http/api_server.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/store_identity.h"
#include "coordinator/store/store_janitor.h"
#include "proto/scene/import/import_budget.h"

namespace tcfarm {
namespace {

struct ServeOptions {
  std::string httpHost = "127.0.0.1";
  int httpPort = 8080;
  FarmOptions farm;
  std::filesystem::path database;
  unsigned localWorkers = 1;  // the embedded local farm: one worker using all cores
  unsigned workerThreads = 0;
  std::string workerBinary;
  std::filesystem::path dashboard;  // static files served at /; empty: none
  uint64_t assetMaxFileBytes = ApiOptions{}.assetMaxFileBytes;
  uint64_t assetMaxJobBytes = ApiOptions{}.assetMaxJobBytes;
  uint64_t importBudgetBytes = 0;  // every scene import at once (--import-budget-mib)
  std::shared_ptr<const http::ApiTokens> tokens;  // null: no authentication
  bool insecureNoAuth = false;  // beyond loopback without tokens or keys, on purpose
  std::filesystem::path tlsCertFile;
  std::filesystem::path tlsKeyFile;
  bool adoptStore = false;
  RetentionPolicy retention;
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

// The running jobs' default share of the memory this process may use (its container's
// limit included): the HTTP server, the frame finisher, workers on this machine and the
// system need the rest.
uint64_t HalfTheUsableMemory() {
  return UsableMemoryBytes().value_or(uint64_t{16} << 30) / 2;  // unknown: assume 16 GiB
}

// The default import budget: a quarter of the memory this process may use, beside the
// running jobs' half, and at most 2 GiB. A scene that needs more even alone is refused with
// 413 import_too_large naming --import-budget-mib.
uint64_t DefaultImportBudget() {
  return std::min(UsableMemoryBytes().value_or(uint64_t{16} << 30) / 4, uint64_t{2048} << 20);
}

// The flags as given, checked for range by the parser; Resolve turns them into options.
struct ServeFlags {
  std::string http = "127.0.0.1:8080";
  std::string zmq = FarmOptions{}.endpoint;
  std::string store = FarmOptions{}.storeRoot.string();
  std::string database;  // empty: STORE/jobs.db
  unsigned localWorkers = 1;
  unsigned workerThreads = 0;
  std::string workerBinary;
  int maxRunningJobs = FarmOptions{}.maxRunningJobs;
  std::string exrCompression = FrameWriterOptions{}.exrCompression;
  unsigned writerThreads = FrameWriterOptions{}.threads;
  std::string dashboard;
  long workerTimeoutMs = HeartbeatPolicy{}.timeout.count();
  uint64_t farmMemoryMib = 0;
  size_t pendingFrameMib = JobRunSettings::kDefaultPendingFrameBytes >> 20;
  uint64_t assetMaxFileMib = ApiOptions{}.assetMaxFileBytes >> 20;
  uint64_t assetMaxJobMib = ApiOptions{}.assetMaxJobBytes >> 20;
  uint64_t importBudgetMib = 0;
  double assetOrphanGraceSeconds = RetentionPolicy::kDefaultOrphanAssetGraceMs / 1000.0;
  std::string apiTokens;
  bool insecureNoAuth = false;
  std::string tlsCert;
  std::string tlsKey;
  bool adoptStore = false;
  std::string curveSecret;  // empty: no CURVE
  std::string workerKeys;
  double keepDays = 0;
  std::string storeBudget;
  // Set when given: their defaults are worked out, not fixed.
  CLI::Option* dashboardOption = nullptr;
  CLI::Option* workerTimeoutOption = nullptr;
  CLI::Option* farmMemoryOption = nullptr;
  CLI::Option* importBudgetOption = nullptr;
  CLI::Option* keepDaysOption = nullptr;
};

void AddServeFlags(CLI::App& serve, ServeFlags& flags) {
  using cli::IntegerFrom;
  serve.add_option("--http", flags.http, "Address of the HTTP API and the dashboard")
      ->type_name("HOST:PORT")
      ->capture_default_str();
  serve.add_option("--zmq", flags.zmq, "ZeroMQ endpoint the workers connect to")
      ->type_name("ENDPOINT")
      ->capture_default_str();
  serve.add_option("--store", flags.store, "Frame store: each job's frames, and the job database")
      ->type_name("DIR")
      ->capture_default_str();
  serve.add_option("--db", flags.database, "Job database (default: STORE/jobs.db)")
      ->type_name("FILE");
  serve.add_flag("--adopt-store", flags.adoptStore,
                 "Bind the job database to a frame store it does not belong to (a fresh database over a "
                 "store with jobs, or one moved to another store); new job ids start above the store's "
                 "highest job folder. Refused when a job folder has the id of one of the database's jobs");
  serve.add_option("--local-workers", flags.localWorkers,
                   "Workers this process starts on loopback (0: the workers run elsewhere)")
      ->type_name("N")
      ->check(IntegerFrom(0, 256))
      ->capture_default_str();
  serve.add_option("--worker-threads", flags.workerThreads,
                   "Tracing threads of each local worker (0: one per core)")
      ->type_name("T")
      ->check(IntegerFrom(0, 4096))
      ->capture_default_str();
  serve.add_option("--worker-binary", flags.workerBinary,
                   "The local workers' program (default: tcfarm-worker beside this one)")
      ->type_name("PATH");
  serve.add_option("--max-running-jobs", flags.maxRunningJobs,
                   "Jobs rendered at once; more wait in the queue")
      ->type_name("K")
      ->check(IntegerFrom(1, 1024))
      ->capture_default_str();
  serve.add_option("--exr-compression", flags.exrCompression,
                   "Lossless EXR compression of the stored frames: zip[:1-9], none, rle, zips or piz")
      ->type_name("NAME")
      ->capture_default_str();
  serve.add_option("--writer-threads", flags.writerThreads, "Threads encoding frames")
      ->type_name("N")
      ->check(IntegerFrom(1, 64))
      ->capture_default_str();
  flags.dashboardOption =
      serve.add_option("--dashboard", flags.dashboard,
                       "Web page served at / (default: services/dashboard of the source tree "
                       "this was built in, when there)")
          ->type_name("DIR");
  flags.workerTimeoutOption =
      serve.add_option("--worker-timeout", flags.workerTimeoutMs,
                       "Silence after which a worker's tasks are requeued")
          ->type_name("MS")
          ->check(IntegerFrom(100, 3600000))
          ->capture_default_str();
  flags.farmMemoryOption =
      serve.add_option("--farm-memory", flags.farmMemoryMib,
                       "All running jobs together, their frames and state; a job waits queued until it "
                       "fits, one that never could is refused (default: half the memory this process may use)")
          ->type_name("MIB")
          ->check(IntegerFrom(1, 1 << 30));
  serve.add_option("--pending-frame-memory", flags.pendingFrameMib,
                   "Per job, frames finished ahead of their turn; beyond it they wait on disk")
      ->type_name("MIB")
      ->check(IntegerFrom(0, 1 << 20))
      ->capture_default_str();
  flags.importBudgetOption =
      serve.add_option("--import-budget-mib", flags.importBudgetMib,
                       "Scene checks and submits together, while they import and decode scenes (glTF, OBJ, meshopt "
                       "and Draco geometry, textures); past it a request waits up to 2 s, then is answered 503 "
                       "with Retry-After (default: a quarter of the memory this process may use, at most 2048)")
          ->type_name("MIB")
          ->check(IntegerFrom(1, 1 << 30));
  serve.add_option("--asset-max-file-mib", flags.assetMaxFileMib,
                   "Largest asset one upload may store (PUT /api/v1/assets); larger is refused")
      ->type_name("MIB")
      ->check(IntegerFrom(1, 1 << 20))
      ->capture_default_str();
  serve.add_option("--asset-max-job-mib", flags.assetMaxJobMib,
                   "Per job, the assets its scene may name together; more is refused")
      ->type_name("MIB")
      ->check(IntegerFrom(1, 1 << 24))
      ->capture_default_str();
  serve.add_option("--asset-orphan-grace-s", flags.assetOrphanGraceSeconds,
                   "Uploaded assets that no job names are removed once they are older than this many seconds: "
                   "the time a client has from uploading a scene's files to submitting it")
      ->type_name("SECONDS")
      ->check(CLI::Range(1.0, 1e9))
      ->capture_default_str();
  serve.add_option("--api-tokens", flags.apiTokens,
                   "API tokens, one a line with its role: 'read TOKEN', 'submit TOKEN' or 'admin TOKEN' "
                   "(also TOKEN ROLE, ROLE:TOKEN); requests then need 'Authorization: Bearer TOKEN'. "
                   "Required when --http is beyond loopback")
      ->type_name("FILE");
  serve.add_option("--tls-cert", flags.tlsCert, "Serve HTTPS with this PEM certificate (chain); needs --tls-key")
      ->type_name("FILE");
  serve.add_option("--tls-key", flags.tlsKey, "The PEM private key of --tls-cert")->type_name("FILE");
  serve.add_option("--curve-secret", flags.curveSecret,
                   "The coordinator's CURVE secret key (tcfarm-coordinator keygen); with --worker-keys, "
                   "workers must authenticate (CurveZMQ) and its public key is printed at start")
      ->type_name("FILE")
      ->envname("TCFARM_CURVE_SECRET");
  serve.add_option("--worker-keys", flags.workerKeys,
                   "Allow-list: every *.pub file here is a worker's public key; read again when it "
                   "changes, so adding a worker needs no restart")
      ->type_name("DIR")
      ->envname("TCFARM_WORKER_KEYS");
  flags.keepDaysOption =
      serve.add_option("--keep-days", flags.keepDays,
                       "Finished jobs (completed, failed, canceled) that finished more than D days ago are deleted "
                       "with their frames, at start and every minute (0: every finished job). Default: kept")
          ->type_name("D")
          ->check(CLI::Range(0.0, 100000.0));
  serve.add_option("--store-budget", flags.storeBudget,
                   "While the store holds more than SIZE (500M, 50G, 2T), the earliest finished jobs are deleted "
                   "with their frames until it fits; checked at start and every minute. Default: no budget")
      ->type_name("SIZE");
  serve.add_flag("--insecure-no-auth", flags.insecureNoAuth,
                 "Serve beyond loopback without authentication: without --api-tokens anyone who reaches "
                 "the HTTP API may submit, cancel and download; without CURVE keys any process that "
                 "reaches the ZeroMQ port can take tasks and return pixels");
}

// 127.0.0.0/8, ::1 and localhost: only this machine reaches them. Anything else (0.0.0.0,
// ::, a host name, an interface's address) may be reached from the network.
bool IsLoopbackHost(const std::string& host) {
  if (host == "localhost" || host == "::1" || host == "[::1]") return true;
  in_addr address{};
  return inet_pton(AF_INET, host.c_str(), &address) == 1 && (ntohl(address.s_addr) >> 24) == 127;
}

void RequireReadable(const std::string& flag, const std::filesystem::path& file) {
  std::error_code error;
  if (!std::ifstream(file) || std::filesystem::is_directory(file, error)) {
    throw std::invalid_argument(flag + " " + file.string() + ": cannot read it; expected a readable PEM file");
  }
}

// Tokens, TLS, and the rule that a coordinator reachable beyond loopback has tokens.
void ResolveSecurity(const ServeFlags& flags, ServeOptions* options) {
  if (!flags.apiTokens.empty()) {
    try {
      options->tokens = std::make_shared<const http::ApiTokens>(http::ApiTokens::Load(flags.apiTokens));
    } catch (const std::invalid_argument& error) {
      throw std::invalid_argument(std::string("--api-tokens ") + error.what());
    }
  }
  options->insecureNoAuth = flags.insecureNoAuth;
  if (!options->tokens && !flags.insecureNoAuth && !IsLoopbackHost(options->httpHost)) {
    throw std::invalid_argument(
        "--http " + flags.http + " is reachable beyond loopback, and without --api-tokens anyone who reaches "
        "it could submit, cancel and download jobs; expected --api-tokens FILE (docs/operations.md, 'API tokens and TLS'), an "
        "address on loopback (127.0.0.1:PORT), or --insecure-no-auth to serve without tokens on purpose");
  }
  if (flags.tlsCert.empty() != flags.tlsKey.empty()) {
    throw std::invalid_argument(std::string(flags.tlsCert.empty() ? "--tls-key" : "--tls-cert") +
                                " is given alone; expected both --tls-cert FILE and --tls-key FILE, or neither");
  }
  if (!flags.tlsCert.empty()) {
    RequireReadable("--tls-cert", flags.tlsCert);
    RequireReadable("--tls-key", flags.tlsKey);
    options->tlsCertFile = flags.tlsCert;
    options->tlsKeyFile = flags.tlsKey;
  }
}

// True for endpoints only this machine can reach: tcp on a loopback address, ipc, inproc.
bool IsLoopbackEndpoint(const std::string& endpoint) {
  if (endpoint.rfind("ipc://", 0) == 0 || endpoint.rfind("inproc://", 0) == 0) return true;
  if (endpoint.rfind("tcp://", 0) != 0) return false;
  const std::string address = endpoint.substr(6);
  const size_t colon = address.rfind(':');
  std::string host = address.substr(0, colon == std::string::npos ? address.size() : colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  return IsLoopbackHost(host);
}

// Both CURVE flags or neither; without them, loopback unless insecurity is asked for.
void ResolveWorkerAuthentication(const ServeFlags& flags, ServeOptions* options) {
  if (flags.curveSecret.empty() != flags.workerKeys.empty()) {
    throw std::invalid_argument(std::string(flags.curveSecret.empty() ? "--worker-keys" : "--curve-secret") +
                                " without " + (flags.curveSecret.empty() ? "--curve-secret" : "--worker-keys") +
                                ": CURVE needs the coordinator's secret key and the workers' allow-list");
  }
  if (flags.curveSecret.empty()) {
    if (!IsLoopbackEndpoint(flags.zmq) && !flags.insecureNoAuth) {
      throw std::invalid_argument(
          "--zmq " + flags.zmq + ": reachable beyond loopback without worker authentication; give "
          "--curve-secret FILE and --worker-keys DIR (make keys with tcfarm-coordinator keygen), or "
          "--insecure-no-auth to let any process that reaches the port take tasks");
    }
    return;
  }
  CurveServerKeys keys;
  try {
    keys.secretKey = curve::ReadSecretKeyFile(flags.curveSecret).secretKey;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--curve-secret ") + e.what());
  }
  if (!std::filesystem::is_directory(flags.workerKeys)) {
    throw std::invalid_argument("--worker-keys " + flags.workerKeys + ": not a folder (expected one holding *.pub files)");
  }
  keys.workerKeysDirectory = flags.workerKeys;
  options->farm.curve = std::move(keys);
}

// Throws std::invalid_argument naming the flag whose value cannot be used.
ServeOptions Resolve(const ServeFlags& flags) {
  ServeOptions options;
  ParseHttpAddress(flags.http, &options);
  options.farm.endpoint = flags.zmq;
  options.farm.storeRoot = flags.store;
  options.database = flags.database;
  options.adoptStore = flags.adoptStore;
  options.localWorkers = flags.localWorkers;
  options.workerThreads = flags.workerThreads;
  options.workerBinary = flags.workerBinary;
  options.farm.maxRunningJobs = flags.maxRunningJobs;
  options.farm.output.exrCompression = flags.exrCompression;
  options.farm.output.threads = flags.writerThreads;
  options.dashboard =
      flags.dashboardOption->count() ? std::filesystem::path(flags.dashboard) : FindDashboard();
  if (flags.workerTimeoutOption->count()) {
    options.farm.heartbeat.SetTimeout(Milliseconds(flags.workerTimeoutMs));
  }
  if (flags.farmMemoryOption->count()) options.farm.farmMemoryBytes = flags.farmMemoryMib << 20;
  options.importBudgetBytes =
      flags.importBudgetOption->count() ? flags.importBudgetMib << 20 : DefaultImportBudget();
  options.farm.pendingFrameBytes = flags.pendingFrameMib << 20;
  options.assetMaxFileBytes = flags.assetMaxFileMib << 20;
  options.assetMaxJobBytes = flags.assetMaxJobMib << 20;
  ResolveSecurity(flags, &options);
  ResolveWorkerAuthentication(flags, &options);
  options.retention.orphanAssetGraceMs = static_cast<int64_t>(flags.assetOrphanGraceSeconds * 1000);
  if (flags.keepDaysOption->count()) {
    options.retention.keepMs = static_cast<int64_t>(flags.keepDays * 24 * 3600 * 1000);
  }
  if (!flags.storeBudget.empty()) {
    try {
      options.retention.budgetBytes = ParseByteSize(flags.storeBudget);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("--store-budget ") + e.what());
    }
  }
  if (!options.dashboard.empty() && !std::filesystem::is_directory(options.dashboard)) {
    throw std::invalid_argument("--dashboard " + options.dashboard.string() + ": not a folder");
  }
  if (options.database.empty()) options.database = options.farm.storeRoot / "jobs.db";
  if (options.farm.farmMemoryBytes == 0) options.farm.farmMemoryBytes = HalfTheUsableMemory();
  if (!IsLosslessExrCompression(options.farm.output.exrCompression)) {
    throw std::invalid_argument("--exr-compression " + options.farm.output.exrCompression +
                                ": expected a lossless one: none, rle, zips, zip or piz");
  }
  return options;
}

// Keys for the coordinator's own local workers when workers must authenticate: a fresh
// pair for each worker at each start (so that a ban of one is not a ban of all), allowed
// in memory, their files in a private temp folder (mode 0700) that goes away with the
// coordinator.
class LocalWorkerKeys {
 public:
  LocalWorkerKeys(const std::string& coordinatorPublicKey, unsigned workers) {
    std::string folder = (std::filesystem::temp_directory_path() / "tcfarm-local-worker-keys-XXXXXX").string();
    if (!::mkdtemp(folder.data())) throw std::runtime_error("cannot make a folder for the local workers' keys in " + folder);
    folder_ = folder;
    for (unsigned i = 0; i < workers; ++i) {
      keys_.push_back(curve::GenerateKeyPair());
      curve::WriteKeyPair(folder_, KeyName(i), keys_.back());
    }
    std::ofstream(folder_ / "coordinator.pub") << "# this coordinator's CURVE public key\n" << coordinatorPublicKey << "\n";
  }
  ~LocalWorkerKeys() {
    std::error_code ignored;
    std::filesystem::remove_all(folder_, ignored);
  }
  std::vector<std::string> PublicKeys() const {
    std::vector<std::string> keys;
    for (const curve::KeyPair& pair : keys_) keys.push_back(pair.publicKey);
    return keys;
  }
  std::vector<std::string> WorkerArguments(unsigned index) const {
    return {"--curve-secret", (folder_ / (KeyName(index) + ".key")).string(), "--coordinator-key",
            (folder_ / "coordinator.pub").string()};
  }

 private:
  static std::string KeyName(unsigned index) { return "local-worker-" + std::to_string(index); }

  std::vector<curve::KeyPair> keys_;
  std::filesystem::path folder_;
};

// Where local workers connect: a wildcard bind is reached through loopback.
std::string LoopbackEndpoint(std::string bound) {
  for (const char* any : {"0.0.0.0", "[::]", "*"}) {
    size_t at = bound.find(any);
    if (at != std::string::npos) bound.replace(at, std::string(any).size(), "127.0.0.1");
  }
  return bound;
}

// Says who may use the API; tokens themselves are never printed.
void ReportAccess(const ServeOptions& options, const char* scheme, int port) {
  if (options.tokens) {
    std::fprintf(stderr, "tcfarm-coordinator: API requests need one of %zu tokens (--api-tokens)\n",
                 options.tokens->size());
  } else if (options.insecureNoAuth) {
    std::fprintf(stderr,
                 "tcfarm-coordinator: WARNING: --insecure-no-auth: the HTTP API at %s://%s:%d takes requests "
                 "from ANYONE who can reach it, without a token: they may submit, cancel and download jobs\n",
                 scheme, options.httpHost.c_str(), port);
  }
}

// One line per job event on stderr: "job 7 frames_written: frames 10..19 written". Names
// come from users: control bytes are escaped, so a name cannot forge a line of the log.
void LogEvent(const JobEvent& event) {
  std::string message;
  for (char c : event.message) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      message += escaped;
    } else {
      message += c;
    }
  }
  std::fprintf(stderr, "job %llu %s: %s\n", static_cast<unsigned long long>(event.job), event.type.c_str(),
               message.c_str());
}

void ReportRetention(const RetentionPolicy& retention) {
  if (retention.keepMs) {
    std::fprintf(stderr, "tcfarm-coordinator: finished jobs are deleted %g days after they finish (--keep-days)\n",
                 static_cast<double>(*retention.keepMs) / (24 * 3600 * 1000.0));
  }
  if (retention.budgetBytes) {
    std::fprintf(stderr,
                 "tcfarm-coordinator: the earliest finished jobs are deleted while the store holds more than %s "
                 "(--store-budget)\n",
                 ShowBytes(*retention.budgetBytes).c_str());
  }
}

int RunServe(const ServeOptions& options) {
  // Frames (megabytes each) are mapped on their own and unmapped when freed, whatever
  // their size: glibc's adaptive threshold would otherwise move them into the heap after
  // the first one is freed, where a job's frames outlive it in the RSS.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  std::signal(SIGPIPE, SIG_IGN);

  std::filesystem::create_directories(options.farm.storeRoot);
  if (options.database.has_parent_path()) {
    std::filesystem::create_directories(options.database.parent_path());
  }
  JobStore store(options.database);
  store.AddEventListener(LogEvent);
  BindDatabaseToStore(store, options.farm.storeRoot, options.adoptStore);
  SystemClock clock;
  FarmOptions farmOptions = options.farm;
  std::unique_ptr<LocalWorkerKeys> localWorkerKeys;
  if (farmOptions.curve && options.localWorkers > 0) {
    localWorkerKeys =
        std::make_unique<LocalWorkerKeys>(curve::PublicKeyOf(farmOptions.curve->secretKey), options.localWorkers);
    for (const std::string& key : localWorkerKeys->PublicKeys()) farmOptions.curve->alsoAllowed.insert(key);
  }
  // One budget for every scene the coordinator imports at once; the API's checks and
  // submits hold it while they import, the referee while it keeps a scene built.
  const auto importBudget = std::make_shared<ImportBudget>(options.importBudgetBytes);
  farmOptions.importBudget = importBudget;  // the referee's scenes too
  Farm farm(store, farmOptions, clock);

  ApiOptions api;
  api.importBudget = importBudget;
  api.host = options.httpHost;
  api.port = options.httpPort;
  api.storeRoot = options.farm.storeRoot;
  api.dashboardDirectory = options.dashboard;
  api.farmMemoryBytes = options.farm.farmMemoryBytes;
  api.pendingFrameBytes = options.farm.pendingFrameBytes;
  api.assetMaxFileBytes = options.assetMaxFileBytes;
  api.assetMaxJobBytes = options.assetMaxJobBytes;
  api.tokens = options.tokens;
  api.tlsCertFile = options.tlsCertFile;
  api.tlsKeyFile = options.tlsKeyFile;
  // One coordinator per store: what a crashed one left half-written is nobody's.
  AssetStore(api.storeRoot / "assets").RemoveLeftovers();
  // Deletes jobs for the API and the retention alike. Its rounds (the store's size, then at
  // its first round deletions left half done, and the retention) run on its own thread
  // from just before the farm loop starts: a deletion waits for the loop to let go of the job.
  StoreJanitor janitor(store, options.farm.storeRoot, [&farm](uint64_t id) { return farm.ReleaseJob(id); },
                       farm.metrics().registry.get(), options.retention);
  ApiServer server(store, farm, farm.metrics().registry, api, &janitor);
  int port = server.Start();

  std::string workerEndpoint = LoopbackEndpoint(farm.BoundEndpoint());
  LocalWorkers localWorkers(options.workerBinary.empty() ? FindWorkerBinary() : options.workerBinary,
                            workerEndpoint, options.workerThreads,
                            [&localWorkerKeys](unsigned index) {
                              return localWorkerKeys ? localWorkerKeys->WorkerArguments(index)
                                                     : std::vector<std::string>{};
                            });
  localWorkers.Start(options.localWorkers);

  // Before the line that says it listens: whoever waits for that line finds this one too.
  if (farmOptions.curve) {
    std::fprintf(stderr,
                 "tcfarm-coordinator: workers authenticate with CURVE; this coordinator's public key is %s "
                 "(workers: --coordinator-key FILE holding it); allowed worker keys: %s/*.pub\n",
                 farm.PublicKey().c_str(), farmOptions.curve->workerKeysDirectory.c_str());
  } else if (!IsLoopbackEndpoint(options.farm.endpoint)) {
    std::fprintf(stderr, "tcfarm-coordinator: --insecure-no-auth: any process that reaches %s may take tasks "
                         "and return pixels\n", options.farm.endpoint.c_str());
  }
  const char* scheme = options.tlsCertFile.empty() ? "http" : "https";
  std::printf("tcfarm-coordinator: listening http=%s://%s:%d zmq=%s workers=%u store=%s\n", scheme,
              options.httpHost.c_str(), port, workerEndpoint.c_str(), options.localWorkers,
              options.farm.storeRoot.c_str());
  std::fflush(stdout);
  if (!options.dashboard.empty()) {
    std::fprintf(stderr, "tcfarm-coordinator: dashboard at %s://%s:%d/ from %s\n", scheme,
                 options.httpHost.c_str(), port, options.dashboard.c_str());
  }
  ReportAccess(options, scheme, port);
  ReportRetention(options.retention);
  janitor.Start();

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
  janitor.Stop();  // a deletion waiting on the farm has been told it stopped
  server.Stop();
  localWorkers.Stop();
  return 0;
}

}  // namespace

cli::Subcommand AddServeCommand(CLI::App& program) {
  CLI::App* serve = program.add_subcommand(
      "serve", "The coordinator daemon: jobs, planning, dispatch to the workers, the frame store, "
               "the HTTP API (with --local-workers, its own workers too)");
  auto flags = std::make_shared<ServeFlags>();
  AddServeFlags(*serve, *flags);
  return {serve, [&program, flags]() {
            ServeOptions options;
            try {
              options = Resolve(*flags);
            } catch (const std::invalid_argument& e) {
              return cli::ReportUsageError(program, e.what());
            }
            return RunServe(options);
          }};
}

}  // namespace tcfarm
