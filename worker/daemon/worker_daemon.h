// `tcfarm-worker serve`: a stateless tracing process. It connects a DEALER socket to the
// coordinator, announces its capacity, traces whatever (frame, pixel set) tasks arrive
// and sends the pixels back. It holds no job state: if it dies, the coordinator
// requeues its tasks; if the coordinator goes silent or says goodbye (DISCONNECT), it
// reconnects with back-off.
//
// With CURVE keys the worker proves who it is to the coordinator (CurveZMQ) and checks the
// coordinator's key; a coordinator that refuses it is asked again only after the
// reconnect back-off, never in a tight loop.
//
// One thread owns the socket and does everything; tracing fans out over the thread pool.
// Tasks are small (tens of milliseconds), so heartbeats still go out on time.
#pragma once

#include <atomic>
#include <deque>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "worker/daemon/asset_cache.h"
#include "worker/daemon/metrics_endpoint.h"
#include "worker/daemon/scene_cache.h"
#include "worker/daemon/worker_metrics.h"
#include "proto/wire/liveness.h"
#include "proto/wire/wire.h"

namespace tcfarm {

// A worker's CURVE keys (Z85): its own pair and the coordinator's public key.
struct CurveClientKeys {
  std::string secretKey;
  std::string publicKey;
  std::string coordinatorKey;
};

struct WorkerOptions {
  std::string coordinator = "tcp://127.0.0.1:5555";
  unsigned threads = 0;  // 0: all cores
  // Tasks in flight: one tracing, the rest queued here so the next starts at once
  // instead of after a round trip to the coordinator.
  uint32_t capacity = 3;
  std::string name;  // shown in the coordinator's worker list; default host:pid
  HeartbeatPolicy heartbeat;
  // Where fetched assets (texture images) are kept by hash; empty: a folder per user under
  // the system's temp directory, shared by the workers of one machine.
  std::filesystem::path assetCache;
  uint64_t maxAssetBytes = uint64_t{4} << 30;
  std::optional<CurveClientKeys> curve;  // none: the NULL mechanism, no authentication
};

class WorkerDaemon {
 public:
  WorkerDaemon(WorkerOptions options, const Clock& clock);
  ~WorkerDaemon();

  // Runs until *stop becomes true; then says DISCONNECT, stops the scene builds under way
  // and returns (the loop notices `stop` within its 100 ms poll, a build at its next look).
  void Run(const std::atomic<bool>& stop);
  const WorkerMetrics& metrics() const { return metrics_; }
  // Safe from any thread (the metrics endpoint asks): the loop stalls when it has not
  // turned for kStallAfter, e.g. stuck in a task that never ends.
  WorkerHealth Health() const;
  static constexpr Milliseconds kStallAfter{30000};

 private:
  void Connect();
  void Reconnect(const std::atomic<bool>& stop);
  // Reads the socket's monitor: a failed handshake (refused key, wrong coordinator key,
  // CURVE on one end only) ends this connection; Reconnect then waits its back-off.
  void CheckHandshake();
  void ReceiveAll();
  void Handle(wire::Message message);
  void OnTask(wire::Task task);
  void OnScene(const wire::SceneData& scene);
  void OnAssetPiece(const wire::AssetPiece& piece);
  void OnCoordinatorError(const wire::Error& error);
  void ForgetScene(const std::string& sceneHash);
  // A parsed scene that names assets this worker lacks: ask for each (once), build later.
  void AwaitAssets(const std::string& sceneHash, SceneCache::Built built, std::vector<wire::Task> tasks);
  void StartBuild(const std::string& sceneHash, std::function<SceneCache::Built(BuildStop)> build,
                  std::vector<wire::Task> tasks);
  // The build gives up at its next look (util/build_stop.h); its tasks are dropped.
  void StopBuild(const std::string& sceneHash);
  void FailTasks(const std::vector<wire::Task>& tasks, const std::string& sceneHash, const std::string& why);
  // Scenes whose build has finished: cached, and their tasks made ready (or failed).
  void CollectBuiltScenes();
  void StopBuilds();
  void TraceNext();
  void Send(const wire::Message& message);

  WorkerOptions options_;
  const Clock& clock_;
  EmbreeDevice device_;
  TracingThreads pool_;
  SceneCache scenes_;
  zmq::context_t context_;
  std::unique_ptr<zmq::socket_t> socket_;
  std::unique_ptr<zmq::socket_t> monitor_;  // socket_'s handshake events
  uint64_t connections_ = 0;                // names each connection's monitor endpoint
  std::string handshakeFailure_;            // why the coordinator refused this connection; "" if it did not
  PeerLiveness coordinator_;
  Backoff backoff_;
  std::deque<wire::Task> ready_;                           // scene at hand
  std::map<std::string, std::vector<wire::Task>> waitingForScene_;
  // Scenes being built off the loop, with the tasks that wait for them: the loop keeps
  // answering heartbeats meanwhile. A scene of millions of triangles takes longer to build
  // than the coordinator waits for a silent worker. A build is stopped when its scene's
  // jobs are gone or the worker stops, rather than hold the worker for as long as a huge
  // scene takes to build.
  struct SceneBuild {
    std::future<SceneCache::Built> built;
    std::vector<wire::Task> tasks;
    std::unique_ptr<std::atomic<bool>> stop;  // at a fixed address: the build thread reads it
  };
  std::map<std::string, SceneBuild> building_;
  AssetCache assets_;
  // Scenes parsed but waiting for assets, by scene hash.
  struct AssetWait {
    std::unique_ptr<Scene> scene;
    std::set<std::string> missing;
    std::vector<wire::Task> tasks;
  };
  std::map<std::string, AssetWait> waitingForAssets_;
  WorkerMetrics metrics_;
  std::atomic<SteadyTime::rep> lastLoopTurn_;
  std::atomic<bool> coordinatorAnswers_{false};
  bool coordinatorLeft_ = false;  // it said DISCONNECT: reconnect without waiting for its silence
};

}  // namespace tcfarm
