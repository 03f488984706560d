#include "coordinator/dispatch/dispatcher.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "proto/curve/curve_keys.h"
#include "proto/curve/socket_events.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {
namespace {

// Messages handled per Poll before the farm loop gets to run: keeps result handling
// from starving task dispatch under a flood.
constexpr int kMaxMessagesPerPoll = 4096;
// How long closing the socket may wait for goodbyes to leave: long enough for loopback
// and a LAN, short enough that a worker that stopped reading cannot hold up a shutdown.
constexpr Milliseconds kGoodbyeLinger{1000};
// Log lines per kind of wrong message: enough to see what a broken or hostile peer
// does, few enough that a flood of them does not flood the log.
constexpr uint64_t kLoggedSamples = 10;

}  // namespace

std::string PrincipalOf(const wire::Peer& peer, const std::string& name) {
  if (!peer.curveKey.empty()) return "key:" + peer.curveKey;
  return "name:" + name + "@" + (peer.address.empty() ? "local" : peer.address);
}

Dispatcher::Dispatcher(const std::string& endpoint, const Clock& clock, HeartbeatPolicy policy,
                       const AssetSource* assets, std::optional<CurveServerKeys> curve)
    : clock_(clock),
      policy_(policy),
      socket_(context_, zmq::socket_type::router),
      registry_(policy),
      lastHeartbeat_(clock.Now()),
      lastDrained_(clock.Now()),
      assets_(assets) {
  socket_.set(zmq::sockopt::linger, 0);
  // Sending to a peer that is gone fails instead of silently vanishing, so the credit
  // it would have held is never taken.
  socket_.set(zmq::sockopt::router_mandatory, 1);
  if (curve) {
    publicKey_ = curve::PublicKeyOf(curve->secretKey);
    socket_.set(zmq::sockopt::curve_server, 1);
    socket_.set(zmq::sockopt::curve_secretkey, curve->secretKey);
    socket_.set(zmq::sockopt::zap_domain, "tcfarm-workers");
    // The monitor is published before the authenticator reads it and before the socket
    // binds: no refused connection goes uncounted.
    const std::string monitor = "inproc://tcfarm-dispatcher-monitor-" + std::to_string(reinterpret_cast<uintptr_t>(this));
    zmq_socket_monitor(socket_.handle(), monitor.c_str(), curve::kHandshakeFailureEvents);
    authenticator_ = std::make_unique<CurveAuthenticator>(context_, *curve, monitor);
  }
  socket_.bind(endpoint);
}

Dispatcher::~Dispatcher() = default;

std::string Dispatcher::BoundEndpoint() const {
  return socket_.get(zmq::sockopt::last_endpoint);
}

void Dispatcher::SetPriority(uint64_t jobId, int priority) { queue_.SetPriority(jobId, priority); }

std::vector<WorkerLoss> Dispatcher::TakeWorkerLosses() {
  std::vector<WorkerLoss> losses;
  losses.swap(losses_);
  return losses;
}

void Dispatcher::AddJob(uint64_t jobId, int priority, uint32_t width, uint32_t height,
                        const std::string& sceneHash, const std::string& sceneJson) {
  queue_.AddJob(jobId, priority, width, height, sceneHash);
  scenes_[sceneHash] = sceneJson;
}

void Dispatcher::RemoveJob(uint64_t jobId) {
  if (!queue_.HasJob(jobId)) return;
  const std::string hash = queue_.JobOf(jobId).sceneHash;
  std::set<std::string> holders;  // workers that held its tasks, and may be building its scene
  for (uint64_t taskId : queue_.RemoveJob(jobId)) {
    if (std::string holder = registry_.Forget(taskId); !holder.empty()) holders.insert(holder);
  }
  if (queue_.SceneUsed(hash)) return;
  scenes_.erase(hash);
  for (const std::string& holder : holders) Send(holder, wire::Error{0, hash, "no job uses this scene any more", ""});
}

void Dispatcher::Enqueue(DispatchTask task) { queue_.Enqueue(std::move(task)); }

void Dispatcher::Receive(Milliseconds timeout, DispatchSink& sink) {
  wire::WaitForInput(socket_, timeout);
  ReceiveAll(sink);
}

void Dispatcher::Flush() {
  SteadyTime now = clock_.Now();
  for (const WorkerRegistry::Expired& silent : registry_.ExpireSilent(lastDrained_)) {
    ++counters_.workersLost;
    std::fprintf(stderr, "coordinator: worker %s went silent; its tasks are requeued\n",
                 silent.name.c_str());
    RequeueLost(silent.name, "went silent", silent.tasks);
  }
  if (authenticator_) {
    counters_.refusedKeys = authenticator_->RefusedKeys();
    counters_.failedHandshakes = authenticator_->FailedHandshakes();
  }
  SendHeartbeats(now);
  DispatchPending();
  SendAssetPieces();
}

void Dispatcher::OnAssetGet(const std::string& identity, const wire::AssetGet& get) {
  const std::optional<uint64_t> size = assets_ ? assets_->SizeOf(get.assetHash) : std::nullopt;
  if (!size) {
    Send(identity, wire::Error{0, "", "the farm has no asset " + get.assetHash, get.assetHash});
    return;
  }
  for (AssetSend& send : assetSends_) {
    // A worker asks again only after it dropped what it had: pieces from where the old
    // download stood would not fit, so the asset starts over.
    if (send.identity == identity && send.hash == get.assetHash) {
      send = AssetSend{identity, get.assetHash, 0, *size};
      return;
    }
  }
  assetSends_.push_back(AssetSend{identity, get.assetHash, 0, *size});
}

void Dispatcher::SendAssetPieces() {
  // Per loop turn: enough to keep a fast link busy, little enough to keep the loop turning.
  constexpr size_t kBytesPerTurn = 2 * wire::kMaxAssetPieceBytes;
  size_t sentThisTurn = 0;
  // A peer that cannot take a piece (its queue is full, or it is gone and not yet expired)
  // waits for the next turn at the back of the queue, so it holds up no one else's.
  size_t refusedInARow = 0;
  while (!assetSends_.empty() && sentThisTurn < kBytesPerTurn && refusedInARow < assetSends_.size()) {
    AssetSend send = std::move(assetSends_.front());
    assetSends_.pop_front();
    if (!registry_.workers().count(send.identity)) continue;  // the worker is gone; so is its request
    wire::AssetPiece piece{send.hash, send.offset, send.totalSize, {}};
    try {
      piece.bytes = assets_->ReadPiece(send.hash, send.offset, wire::kMaxAssetPieceBytes);
    } catch (const std::runtime_error& error) {
      Send(send.identity, wire::Error{0, "", std::string("the farm cannot read asset ") + error.what(), send.hash});
      continue;
    }
    if (piece.bytes.empty() && send.offset < send.totalSize) {
      Send(send.identity, wire::Error{0, "", "asset " + send.hash + " ends before its size", send.hash});
      continue;
    }
    if (!Send(send.identity, piece)) {
      assetSends_.push_back(std::move(send));
      ++refusedInARow;
      continue;
    }
    refusedInARow = 0;
    sentThisTurn += piece.bytes.size();
    counters_.assetBytesSent += piece.bytes.size();
    send.offset += piece.bytes.size();
    if (piece.IsLast()) {
      ++counters_.assetsSent;
    } else {
      assetSends_.push_back(std::move(send));
    }
  }
}

void Dispatcher::ReceiveAll(DispatchSink& sink) {
  for (int i = 0; i < kMaxMessagesPerPoll; ++i) {
    wire::Peer peer;
    auto parts = wire::ReceivePartsFrom(socket_, peer);
    if (!parts) {
      lastDrained_ = clock_.Now();
      return;
    }
    if (parts->size() < 2) {
      ++counters_.malformed;
      continue;
    }
    std::string identity = std::move(parts->front());
    parts->erase(parts->begin());
    try {
      Handle(identity, peer, wire::Decode(*parts), sink);
    } catch (const wire::WireError& e) {
      if (counters_.malformed++ < 10) {
        std::fprintf(stderr, "coordinator: dropped a malformed message: %s\n", e.what());
      }
      // A registered worker that breaks the protocol may be answering one of its tasks
      // (a RESULT refused before its task could be told): it would never answer it
      // properly, and the job would wait on it. Its tasks go to the others.
      if (!distrusted_.count(identity) && registry_.Find(identity)) {
        DropWorker(identity, std::string("it sent a malformed message (") + e.what() + ")");
      }
    }
  }
}

void Dispatcher::Handle(const std::string& identity, const wire::Peer& peer, wire::Message message,
                        DispatchSink& sink) {
  SteadyTime now = clock_.Now();
  if (distrusted_.count(identity)) {
    ++counters_.distrustedMessages;  // not even DISCONNECT: it gets nothing from us
    return;
  }
  if (auto* ready = std::get_if<wire::Ready>(&message)) {
    OnReady(identity, peer, *ready);
    return;
  }
  if (!registry_.OnHeard(identity, now)) {
    // A worker we expired (or never met): ask it to reconnect and say READY again. It
    // holds no task, so a RESULT or ERROR from it settles nothing (IsHolder counts it).
    ++counters_.unexpected;
    Send(identity, wire::Disconnect{});
    if (auto* result = std::get_if<wire::Result>(&message)) IsHolder(identity, result->taskId);
    if (auto* error = std::get_if<wire::Error>(&message)) IsHolder(identity, error->taskId);
    return;
  }
  if (auto* result = std::get_if<wire::Result>(&message)) {
    OnResult(identity, std::move(*result), sink);
  } else if (auto* get = std::get_if<wire::SceneGet>(&message)) {
    auto scene = scenes_.find(get->sceneHash);
    if (scene != scenes_.end()) {
      Send(identity, wire::SceneData{get->sceneHash, scene->second});
      ++counters_.scenesSent;
    } else {
      Send(identity, wire::Error{0, get->sceneHash, "no job uses this scene any more", ""});
    }
  } else if (auto* assetGet = std::get_if<wire::AssetGet>(&message)) {
    OnAssetGet(identity, *assetGet);
  } else if (auto* error = std::get_if<wire::Error>(&message)) {
    OnError(identity, *error, sink);
  } else if (std::holds_alternative<wire::Disconnect>(message)) {
    RemoveAndRequeue(identity, "left");
  } else if (!std::holds_alternative<wire::Heartbeat>(message)) {
    ++counters_.unexpected;  // TASK or SCENE from a worker: not its role
  }
}

void Dispatcher::OnReady(const std::string& identity, const wire::Peer& peer, const wire::Ready& ready) {
  const WorkerState* known = registry_.Find(identity);
  // A connection keeps the principal it first said READY as: a new name on the same
  // connection is no new worker.
  const std::string principal = known ? known->principal : PrincipalOf(peer, ready.name);
  if (banned_.count(principal)) {
    // A banned worker back on a new connection: as deaf to it as to the old one.
    distrusted_.insert(identity);
    if (counters_.bannedReconnects++ < kLoggedSamples) {
      std::fprintf(stderr, "coordinator: ignored worker %s: %s is banned for returning wrong values\n",
                   ready.name.c_str(), principal.c_str());
    }
    return;
  }
  const std::string name = known ? known->name : ready.name;
  RequeueLost(name, "restarted", registry_.OnReady(identity, ready, principal, clock_.Now()));
}

bool Dispatcher::IsHolder(const std::string& identity, uint64_t taskId) {
  const TaskQueue::Entry* entry = queue_.Find(taskId);
  if (!entry || entry->pending) {
    ++counters_.duplicateResults;  // settled, requeued, or its job is gone: harmless
    return false;
  }
  if (entry->holder == identity) return true;
  if (counters_.foreignReplies++ < kLoggedSamples) {
    const WorkerState* sender = registry_.Find(identity);
    std::fprintf(stderr, "coordinator: dropped a reply for task %llu from %s; it was given to another worker\n",
                 static_cast<unsigned long long>(taskId), sender ? sender->name.c_str() : "an unknown connection");
  }
  return false;
}

std::string Dispatcher::ResultMismatch(const DispatchTask& task, const wire::Result& result) {
  if (result.jobId != task.jobId) return "job " + std::to_string(result.jobId) + " instead of " + std::to_string(task.jobId);
  if (result.frame != task.frame) return "frame " + std::to_string(result.frame) + " instead of " + std::to_string(task.frame);
  if (result.PixelCount() != task.pixels.size()) {
    return std::to_string(result.PixelCount()) + " pixels instead of " + std::to_string(task.pixels.size());
  }
  if (result.horizons.empty() != (task.window == 0)) {
    return task.window == 0 ? "horizons for a task without a window" : "no horizons for a task with a window";
  }
  // 64-bit so that a job's last frames cannot overflow the bound.
  const long long highest = static_cast<long long>(task.frame) + task.window + 1;
  for (int32_t horizon : result.horizons) {
    if (horizon <= task.frame || horizon > highest) {
      return "horizon " + std::to_string(horizon) + " outside " + std::to_string(task.frame + 1) + " .. " +
             std::to_string(highest);
    }
  }
  return "";
}

void Dispatcher::DropWorker(const std::string& identity, const std::string& why) {
  const WorkerState* worker = registry_.Find(identity);
  std::fprintf(stderr, "coordinator: dropped worker %s: %s; its tasks are requeued\n",
               worker ? worker->name.c_str() : "?", why.c_str());
  ++counters_.workersDropped;
  RemoveAndRequeue(identity, "was dropped: " + why);
  Send(identity, wire::Disconnect{});
}

bool Dispatcher::Distrust(const std::string& principal, const std::string& why) {
  if (!banned_.insert(principal).second) return false;
  ++counters_.workersDistrusted;
  for (const std::string& identity : registry_.IdentitiesOf(principal)) {
    DropWorker(identity, "it returned wrong values: " + why);
    distrusted_.insert(identity);
  }
  return true;
}

const WorkerState* Dispatcher::FindPrincipal(const std::string& principal) const {
  for (const auto& [identity, worker] : registry_.workers()) {
    if (worker.principal == principal) return &worker;
  }
  return nullptr;
}

std::vector<DispatchTask> Dispatcher::TakeStranded() {
  std::vector<DispatchTask> stranded =
      queue_.TakeStranded([this](const TaskQueue::Entry& entry) { return AnyWorkerMayTake(entry); });
  counters_.tasksStranded += stranded.size();
  return stranded;
}

void Dispatcher::OnResult(const std::string& identity, wire::Result&& result,
                          DispatchSink& sink) {
  if (!IsHolder(identity, result.taskId)) return;
  TaskQueue::Entry& entry = *queue_.Find(result.taskId);
  const std::string wrong = ResultMismatch(entry.task, result);
  if (!wrong.empty()) {
    // A wrong answer to its own task: nothing it sends can be trusted. The pixels are
    // still owed, so its tasks go to the others.
    ++counters_.unexpected;
    DropWorker(identity, "result for task " + std::to_string(result.taskId) + " has " + wrong);
    return;
  }
  registry_.Release(identity, result.taskId);
  WorkerState& worker = *registry_.Find(identity);  // a task's holder is always registered
  ++worker.tasksDone;
  worker.pixelsDone += result.PixelCount();
  worker.traceSeconds += result.traceSeconds;
  ++counters_.resultsReceived;
  counters_.pixelsReceived += result.PixelCount();
  const double latency = std::chrono::duration<double>(clock_.Now() - entry.sentAt).count();
  const DispatchTask answered = std::move(entry.task);
  queue_.Erase(result.taskId);
  sink.OnResult(answered, std::move(result), latency, worker);
}

void Dispatcher::OnError(const std::string& identity, const wire::Error& error,
                         DispatchSink& sink) {
  if (error.taskId == 0 || !IsHolder(identity, error.taskId)) return;
  registry_.Release(identity, error.taskId);
  TaskQueue::Entry& entry = *queue_.Find(error.taskId);
  entry.failedBy.insert(identity);
  if (entry.failedBy.size() < kWorkersThatMustFailATask) {
    // It may be this worker's fault (a full disk, a broken cache): another worker tries.
    entry.firstError = error.message;
    ++counters_.taskErrorsRetried;
    const WorkerState* worker = registry_.Find(identity);
    std::fprintf(stderr, "coordinator: worker %s could not trace task %llu (%s); another worker will\n",
                 worker ? worker->name.c_str() : "?", static_cast<unsigned long long>(error.taskId),
                 error.message.c_str());
    Requeue({error.taskId});
    return;
  }
  ++counters_.tasksFailed;
  uint64_t jobId = entry.task.jobId, plannerTaskId = entry.task.plannerTaskId;
  const std::string why = entry.firstError == error.message
                              ? error.message
                              : entry.firstError + "; on another worker: " + error.message;
  queue_.Erase(error.taskId);
  sink.OnTaskFailed(jobId, plannerTaskId, why);
}

std::map<uint64_t, size_t> Dispatcher::Requeue(const std::vector<uint64_t>& taskIds) {
  std::map<uint64_t, size_t> requeued = queue_.Requeue(taskIds);
  for (const auto& [jobId, tasks] : requeued) counters_.requeued += tasks;
  return requeued;
}

void Dispatcher::RequeueLost(const std::string& name, const std::string& why, const std::vector<uint64_t>& taskIds) {
  std::map<uint64_t, size_t> requeued = Requeue(taskIds);
  if (!requeued.empty()) losses_.push_back({name, why, std::move(requeued)});
}

void Dispatcher::RemoveAndRequeue(const std::string& identity, const std::string& why) {
  const WorkerState* worker = registry_.Find(identity);
  const std::string name = worker ? worker->name : "an unknown worker";
  RequeueLost(name, why, registry_.Remove(identity));
}

void Dispatcher::SendHeartbeats(SteadyTime now) {
  if (now - lastHeartbeat_ < policy_.interval) return;
  lastHeartbeat_ = now;
  for (const auto& [identity, worker] : registry_.workers()) Send(identity, wire::Heartbeat{});
}

bool Dispatcher::AnyWorkerMayTake(const TaskQueue::Entry& entry) const {
  for (const auto& [identity, worker] : registry_.workers()) {
    if (TaskQueue::MayTake(entry, worker)) return true;
  }
  return false;
}

void Dispatcher::DispatchPending() {
  // Workers for which no pending task is allowed (they failed every one) sit this turn out.
  std::set<std::string> nothingFor;
  while (queue_.Pending() > 0) {
    WorkerState* worker = registry_.MostAvailable(nothingFor);
    if (!worker) return;
    const uint64_t id = queue_.TakeFor(*worker);
    if (id == 0) {
      nothingFor.insert(worker->identity);
      continue;
    }
    const TaskQueue::Entry& entry = queue_.Sent(id, worker->identity, clock_.Now());
    const TaskQueue::Job& job = queue_.JobOf(entry.task.jobId);
    const DispatchTask& t = entry.task;
    wire::Task message{id, t.jobId, job.sceneHash, t.frame, job.width, job.height, t.pixels,
                       t.window};
    registry_.Assign(worker->identity, id);
    ++counters_.tasksSent;
    if (!Send(worker->identity, message)) {
      // Gone between its last message and now: take the task back; expiry removes it.
      RemoveAndRequeue(worker->identity, "could not be reached");
    }
  }
}

bool Dispatcher::Send(const std::string& identity, const wire::Message& message) {
  try {
    return wire::SendMessageTo(socket_, identity, message);
  } catch (const zmq::error_t&) {
    return false;  // router_mandatory: the peer is gone
  }
}

void Dispatcher::SayGoodbye() {
  for (const auto& [identity, worker] : registry_.workers()) Send(identity, wire::Disconnect{});
  // The socket closes right after; without linger the goodbyes would die in its queue.
  socket_.set(zmq::sockopt::linger, static_cast<int>(kGoodbyeLinger.count()));
}

}  // namespace tcfarm
