#include "worker/daemon/worker_daemon.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iterator>
#include <thread>

#include "proto/curve/socket_events.h"
#include "proto/wire/content_hash.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {
namespace {

// Poll timeout while idle: bounds how late a heartbeat or a stop request is noticed.
constexpr long kIdlePollMs = 100;

std::string DefaultName() {
  char host[256] = "worker";
  gethostname(host, sizeof host - 1);
  return std::string(host) + ":" + std::to_string(getpid());
}

std::vector<uint32_t> PixelIndices(const PixelSet& pixels) {
  std::vector<uint32_t> indices;
  indices.reserve(pixels.size());
  pixels.ForEach([&](uint32_t index) { indices.push_back(index); });
  return indices;
}

// Why a task cannot be traced with this scene, or "" when it can.
std::string TaskMismatch(const wire::Task& task, const Scene& scene) {
  const RenderSettings& r = scene.render;
  if (task.width != static_cast<uint32_t>(r.width) ||
      task.height != static_cast<uint32_t>(r.height)) {
    return "task is " + std::to_string(task.width) + "x" + std::to_string(task.height) +
           " but the scene renders " + std::to_string(r.width) + "x" + std::to_string(r.height);
  }
  if (task.frame < r.firstFrame || task.frame > r.LastFrame()) {
    return "frame " + std::to_string(task.frame) + " is outside the scene's frames " +
           std::to_string(r.firstFrame) + ":" + std::to_string(r.LastFrame());
  }
  return "";
}

std::filesystem::path AssetCacheDir(const std::filesystem::path& chosen) {
  if (!chosen.empty()) return chosen;
  return std::filesystem::temp_directory_path() / ("tcfarm-assets-" + std::to_string(getuid()));
}

}  // namespace

WorkerDaemon::WorkerDaemon(WorkerOptions options, const Clock& clock)
    : options_(std::move(options)),
      clock_(clock),
      pool_(options_.threads),
      scenes_(device_, pool_),
      coordinator_(options_.heartbeat, clock.Now()),
      backoff_(options_.heartbeat),
      assets_(AssetCacheDir(options_.assetCache), options_.maxAssetBytes),
      lastLoopTurn_(clock.Now().time_since_epoch().count()) {
  if (options_.name.empty()) options_.name = DefaultName();
  metrics_.threads.Set(pool_.ThreadCount());
}

WorkerHealth WorkerDaemon::Health() const {
  const SteadyTime lastTurn{SteadyTime::duration(lastLoopTurn_.load())};
  return WorkerHealth{clock_.Now() - lastTurn < kStallAfter, coordinatorAnswers_.load()};
}

// Also when Run ended by an exception: the builds under way must not hold the exit.
WorkerDaemon::~WorkerDaemon() { StopBuilds(); }

void WorkerDaemon::Connect() {
  socket_ = std::make_unique<zmq::socket_t>(context_, zmq::socket_type::dealer);
  socket_->set(zmq::sockopt::linger, 0);
  if (options_.curve) {
    socket_->set(zmq::sockopt::curve_serverkey, options_.curve->coordinatorKey);
    socket_->set(zmq::sockopt::curve_publickey, options_.curve->publicKey);
    socket_->set(zmq::sockopt::curve_secretkey, options_.curve->secretKey);
  }
  // Watched before it connects, so that no refusal goes unseen.
  const std::string monitor = "inproc://tcfarm-worker-monitor-" + std::to_string(++connections_);
  zmq_socket_monitor(socket_->handle(), monitor.c_str(), curve::kHandshakeFailureEvents);
  monitor_ = std::make_unique<zmq::socket_t>(context_, zmq::socket_type::pair);
  monitor_->set(zmq::sockopt::linger, 0);
  monitor_->connect(monitor);
  handshakeFailure_.clear();
  socket_->connect(options_.coordinator);
  coordinator_ = PeerLiveness(options_.heartbeat, clock_.Now());
  Send(wire::Ready{options_.capacity, pool_.ThreadCount(), options_.name});
}

// Everything queued belonged to the old connection: the coordinator requeues it.
void WorkerDaemon::Reconnect(const std::atomic<bool>& stop) {
  metrics_.reconnects.Increment();
  coordinatorAnswers_ = false;
  metrics_.coordinatorUp.Set(0);
  ready_.clear();
  waitingForScene_.clear();
  waitingForAssets_.clear();
  assets_.AbandonDownloads();
  for (auto& [hash, build] : building_) build.tasks.clear();  // the scene itself is still worth having
  monitor_.reset();
  socket_.reset();
  Milliseconds delay = backoff_.Next();
  const std::string why = !handshakeFailure_.empty() ? "refused this worker: " + handshakeFailure_
                          : coordinatorLeft_         ? "said goodbye"
                                                     : "silent";
  std::fprintf(stderr, "worker %s: coordinator %s %s; reconnecting in %lld ms\n",
               options_.name.c_str(), options_.coordinator.c_str(), why.c_str(),
               static_cast<long long>(delay.count()));
  coordinatorLeft_ = false;
  for (auto waited = Milliseconds(0); waited < delay && !stop; waited += Milliseconds(50)) {
    std::this_thread::sleep_for(Milliseconds(50));
  }
  Connect();
}

void WorkerDaemon::Send(const wire::Message& message) {
  if (socket_ && wire::SendMessage(*socket_, message)) coordinator_.OnSent(clock_.Now());
}

void WorkerDaemon::Run(const std::atomic<bool>& stop) {
  Connect();
  while (!stop) {
    wire::WaitForInput(*socket_, std::chrono::milliseconds(ready_.empty() ? kIdlePollMs : 0));
    ReceiveAll();
    CheckHandshake();
    CollectBuiltScenes();
    if (!ready_.empty() && !coordinatorLeft_) TraceNext();
    SteadyTime now = clock_.Now();
    lastLoopTurn_ = now.time_since_epoch().count();
    if (coordinatorLeft_ || !handshakeFailure_.empty() || coordinator_.IsDead(now)) {
      Reconnect(stop);
      continue;
    }
    if (coordinator_.ShouldSendHeartbeat(now)) Send(wire::Heartbeat{});
  }
  Send(wire::Disconnect{});
  StopBuilds();
}

void WorkerDaemon::StopBuilds() {
  for (auto& [hash, build] : building_) *build.stop = true;
  building_.clear();  // waits for each build, which now throws BuildStopped at its next look
}

void WorkerDaemon::StopBuild(const std::string& sceneHash) {
  auto build = building_.find(sceneHash);
  if (build == building_.end()) return;
  *build->second.stop = true;
  build->second.tasks.clear();  // CollectBuiltScenes forgets the build once it has given up
}

void WorkerDaemon::CheckHandshake() {
  while (auto event = curve::ReadSocketEvent(*monitor_)) {
    if (event->event & curve::kHandshakeFailureEvents) {
      metrics_.handshakesRefused.Increment();
      handshakeFailure_ = curve::DescribeHandshakeFailure(*event);
    }
  }
}

void WorkerDaemon::ReceiveAll() {
  while (auto parts = wire::ReceiveParts(*socket_)) {
    try {
      wire::Message message = wire::Decode(*parts);
      coordinator_.OnHeard(clock_.Now());  // only a well-formed message proves liveness
      if (!coordinatorAnswers_.exchange(true)) metrics_.coordinatorUp.Set(1);
      Handle(std::move(message));
    } catch (const wire::WireError& e) {
      // Never trusted, never fatal: count it and go on.
      metrics_.messagesMalformed.Increment();
      if (metrics_.messagesMalformed.Value() <= 10) {
        std::fprintf(stderr, "worker %s: dropped a malformed message: %s\n",
                     options_.name.c_str(), e.what());
      }
    }
  }
}

void WorkerDaemon::Handle(wire::Message message) {
  backoff_.Reset();
  if (auto* task = std::get_if<wire::Task>(&message)) {
    OnTask(std::move(*task));
  } else if (auto* scene = std::get_if<wire::SceneData>(&message)) {
    OnScene(*scene);
  } else if (auto* piece = std::get_if<wire::AssetPiece>(&message)) {
    OnAssetPiece(*piece);
  } else if (auto* error = std::get_if<wire::Error>(&message)) {
    OnCoordinatorError(*error);
  } else if (std::holds_alternative<wire::Disconnect>(message)) {
    // The coordinator is going away: reconnect now rather than after its silence.
    coordinatorLeft_ = true;
  }
  // HEARTBEAT only proves liveness; other commands are not for workers.
}

void WorkerDaemon::OnTask(wire::Task task) {
  if (scenes_.Find(task.sceneHash)) {
    metrics_.sceneCacheHits.Increment();
    ready_.push_back(std::move(task));
    return;
  }
  if (auto build = building_.find(task.sceneHash); build != building_.end()) {
    build->second.tasks.push_back(std::move(task));
    return;
  }
  if (auto wait = waitingForAssets_.find(task.sceneHash); wait != waitingForAssets_.end()) {
    wait->second.tasks.push_back(std::move(task));
    return;
  }
  auto& waiting = waitingForScene_[task.sceneHash];
  if (waiting.empty()) {
    metrics_.sceneCacheMisses.Increment();
    Send(wire::SceneGet{task.sceneHash});
  }
  waiting.push_back(std::move(task));
}

void WorkerDaemon::OnScene(const wire::SceneData& scene) {
  auto waiting = waitingForScene_.find(scene.sceneHash);
  if (waiting == waitingForScene_.end()) return;  // not asked for (or asked by an old connection)
  std::vector<wire::Task> tasks = std::move(waiting->second);
  waitingForScene_.erase(waiting);
  if (wire::Sha256Hex(scene.sceneJson) != scene.sceneHash) {
    FailTasks(tasks, scene.sceneHash, "scene bytes do not match hash " + scene.sceneHash);
    return;
  }
  StartBuild(scene.sceneHash,
             [this, json = scene.sceneJson](BuildStop stop) { return scenes_.Build(json, assets_, stop); },
             std::move(tasks));
}

void WorkerDaemon::StartBuild(const std::string& sceneHash, std::function<SceneCache::Built(BuildStop)> build,
                              std::vector<wire::Task> tasks) {
  auto stop = std::make_unique<std::atomic<bool>>(false);
  auto built = std::async(std::launch::async, std::move(build), stop.get());
  building_[sceneHash] = SceneBuild{std::move(built), std::move(tasks), std::move(stop)};
  metrics_.sceneBuilds.Set(static_cast<double>(building_.size()));
}

void WorkerDaemon::FailTasks(const std::vector<wire::Task>& tasks, const std::string& sceneHash, const std::string& why) {
  metrics_.sceneErrors.Increment();
  for (const auto& task : tasks) Send(wire::Error{task.taskId, sceneHash, why, ""});
}

void WorkerDaemon::CollectBuiltScenes() {
  std::vector<wire::Task> askAgain;  // came for a scene whose build had been stopped
  for (auto build = building_.begin(); build != building_.end();) {
    if (build->second.built.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      ++build;
      continue;
    }
    std::string problem;
    SceneCache::Built built;
    bool stopped = false;
    try {
      built = build->second.built.get();
    } catch (const BuildStopped&) {
      stopped = true;
    } catch (const std::exception& e) {
      problem = e.what();
    }
    if (stopped) {
      std::move(build->second.tasks.begin(), build->second.tasks.end(), std::back_inserter(askAgain));
    } else if (!problem.empty()) {
      FailTasks(build->second.tasks, build->first, problem);
    } else if (!built.missingAssets.empty()) {
      AwaitAssets(build->first, std::move(built), std::move(build->second.tasks));
    } else {
      scenes_.Insert(build->first, std::move(built));
      for (auto& task : build->second.tasks) ready_.push_back(std::move(task));
    }
    build = building_.erase(build);
  }
  metrics_.sceneBuilds.Set(static_cast<double>(building_.size()));
  for (auto& task : askAgain) OnTask(std::move(task));
}

void WorkerDaemon::AwaitAssets(const std::string& sceneHash, SceneCache::Built built, std::vector<wire::Task> tasks) {
  AssetWait& wait = waitingForAssets_[sceneHash];
  wait.scene = std::move(built.scene);
  wait.missing.insert(built.missingAssets.begin(), built.missingAssets.end());
  wait.tasks.insert(wait.tasks.end(), std::make_move_iterator(tasks.begin()), std::make_move_iterator(tasks.end()));
  for (const std::string& asset : wait.missing) {
    if (assets_.IsExpected(asset)) continue;
    assets_.Expect(asset);
    metrics_.assetsFetched.Increment();
    Send(wire::AssetGet{asset});
  }
}

void WorkerDaemon::OnAssetPiece(const wire::AssetPiece& piece) {
  std::string problem;
  const AssetCache::Outcome outcome = assets_.Accept(piece, &problem);
  if (outcome == AssetCache::Outcome::kIgnored) return;  // not asked for (or asked by an old connection)
  metrics_.assetBytes.Increment(static_cast<double>(piece.bytes.size()));
  if (outcome == AssetCache::Outcome::kIncomplete) return;
  for (auto wait = waitingForAssets_.begin(); wait != waitingForAssets_.end();) {
    if (!wait->second.missing.count(piece.assetHash)) {
      ++wait;
      continue;
    }
    if (outcome == AssetCache::Outcome::kFailed) {
      FailTasks(wait->second.tasks, wait->first, problem);
      wait = waitingForAssets_.erase(wait);
      continue;
    }
    wait->second.missing.erase(piece.assetHash);
    if (wait->second.missing.empty()) {
      auto scene = std::make_shared<std::unique_ptr<Scene>>(std::move(wait->second.scene));
      StartBuild(wait->first,
                 [this, scene](BuildStop stop) { return scenes_.Finish(std::move(*scene), assets_, stop); },
                 std::move(wait->second.tasks));
      wait = waitingForAssets_.erase(wait);
    } else {
      ++wait;
    }
  }
  if (outcome == AssetCache::Outcome::kFailed) {
    std::fprintf(stderr, "worker %s: %s\n", options_.name.c_str(), problem.c_str());
  }
}

// The coordinator cannot serve a scene or an asset we asked for, or says unasked that no
// job uses a scene any more (its job is gone): the tasks that wait on it are dropped (the
// scene's build stopped), or failed with its reason. The reason names the asset
// as a download's own failures do: the coordinator's message need not.
void WorkerDaemon::OnCoordinatorError(const wire::Error& error) {
  if (!error.sceneHash.empty()) ForgetScene(error.sceneHash);
  if (error.assetHash.empty()) return;
  if (!assets_.IsExpected(error.assetHash)) return;
  assets_.AbandonDownload(error.assetHash);
  const std::string why = "asset " + error.assetHash + ": " + error.message;
  for (auto wait = waitingForAssets_.begin(); wait != waitingForAssets_.end();) {
    if (wait->second.missing.count(error.assetHash)) {
      FailTasks(wait->second.tasks, wait->first, why);
      wait = waitingForAssets_.erase(wait);
    } else {
      ++wait;
    }
  }
}

// No job uses the scene any more (the last was canceled or deleted): its tasks are gone
// from the coordinator, so whatever waits here for the scene is dropped, and its build,
// however long it would take, stopped.
void WorkerDaemon::ForgetScene(const std::string& sceneHash) {
  waitingForScene_.erase(sceneHash);
  waitingForAssets_.erase(sceneHash);
  StopBuild(sceneHash);
  ready_.erase(std::remove_if(ready_.begin(), ready_.end(), [&](const wire::Task& task) { return task.sceneHash == sceneHash; }),
               ready_.end());
}

void WorkerDaemon::TraceNext() {
  wire::Task task = std::move(ready_.front());
  ready_.pop_front();
  Tracer* tracer = scenes_.Find(task.sceneHash);
  if (!tracer) {  // evicted by a newer scene since it was queued: fetch it again
    OnTask(std::move(task));
    return;
  }
  std::string mismatch = TaskMismatch(task, tracer->scene());
  if (!mismatch.empty()) {
    Send(wire::Error{task.taskId, task.sceneHash, mismatch, ""});
    return;
  }
  std::vector<uint32_t> indices = PixelIndices(task.pixels);
  wire::Result result;
  result.taskId = task.taskId;
  result.jobId = task.jobId;
  result.frame = task.frame;
  result.rgb.resize(indices.size() * 3);
  if (task.window > 0) result.horizons.resize(indices.size());
  RayCounts before = tracer->Counts();
  const SceneGeometry::DeformationWork deformedBefore = tracer->DeformationCounts();
  const double cpuBefore = tracer->CpuSeconds();
  auto start = std::chrono::steady_clock::now();
  tracer->TracePixels(task.frame, indices.data(), indices.size(), result.rgb.data(), task.window,
                      task.window > 0 ? result.horizons.data() : nullptr);
  result.traceSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.traceCpuSeconds = std::max(0.0, tracer->CpuSeconds() - cpuBefore);
  const RayCounts after = tracer->Counts();
  const RayCounts rays{after.primary - before.primary, after.shadow - before.shadow,
                       after.reflection - before.reflection, after.refraction - before.refraction};
  result.primaryRays = rays.primary;
  result.shadowRays = rays.shadow;
  result.reflectionRays = rays.reflection;
  result.refractionRays = rays.refraction;
  metrics_.RecordTask(indices.size(), rays, result.traceSeconds, *result.traceCpuSeconds);
  const SceneGeometry::DeformationWork deformedAfter = tracer->DeformationCounts();
  metrics_.RecordDeformation({deformedAfter.posesComputed - deformedBefore.posesComputed,
                              deformedAfter.posesShared - deformedBefore.posesShared,
                              deformedAfter.verticesDeformed - deformedBefore.verticesDeformed});
  Send(result);
}

}  // namespace tcfarm
