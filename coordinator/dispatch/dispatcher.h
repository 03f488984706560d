// The coordinator's end of the wire: a ROUTER socket, the worker registry, and the
// queue of tasks waiting for a worker.
//
// Flow control is by credit: a worker gets at most `capacity` tasks in flight, and each
// RESULT or ERROR returns one. A task belongs to the worker it was given to: a RESULT or
// ERROR for it from anyone else is dropped and counted. One worker's ERROR sends the task
// to a different worker; only a second worker's ERROR fails it. A worker whose RESULT for
// its own task is malformed is dropped (told DISCONNECT, its tasks requeued).
//
// With CURVE keys the ROUTER is a CurveZMQ server and only workers whose public key is on
// the allow-list get through (dispatch/curve_authenticator.h). Jobs share the workers by stride scheduling weighted by
// priority, so a long job cannot starve a short one. A worker that dies or goes silent
// has its tasks requeued: no pixel is lost. Every inbound message is decoded and
// validated; anything malformed is dropped and counted.
//
// Not thread-safe: one thread (the farm loop) owns the dispatcher and its socket.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include <zmq.hpp>

#include "coordinator/dispatch/curve_authenticator.h"
#include "coordinator/dispatch/task_queue.h"
#include "coordinator/dispatch/worker_registry.h"
#include "proto/pixel_set/pixel_set.h"
#include "proto/wire/liveness.h"
#include "proto/wire/wire.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {

// Who a worker is, beyond one connection: its CURVE public key where the coordinator
// authenticates keys (ZAP accepted it, so it cannot be claimed by anyone else); otherwise
// the name it gives and the address it connects from, which is all there is to go on.
std::string PrincipalOf(const wire::Peer& peer, const std::string& name);

// Where the dispatcher delivers what workers send back.
class DispatchSink {
 public:
  virtual ~DispatchSink() = default;
  // task: the one the result answers. latencySeconds: from sending the task to
  // receiving its result. worker: who traced it, its tasksDone counting this one; its
  // principal (PrincipalOf) is what checks that must go to someone else avoid, and what
  // a worker found returning wrong values is banned as.
  virtual void OnResult(const DispatchTask& task, wire::Result&& result, double latencySeconds,
                        const WorkerState& worker) = 0;
  virtual void OnTaskFailed(uint64_t jobId, uint64_t plannerTaskId, const std::string& why) = 0;
};

// Where the dispatcher reads the assets (texture images) workers ask for by hash: the
// farm's asset store. Reads happen on the farm loop, one bounded piece at a time.
class AssetSource {
 public:
  virtual ~AssetSource() = default;
  virtual std::optional<uint64_t> SizeOf(const std::string& hash) const = 0;
  // Up to maxBytes of the asset from offset. Throws std::runtime_error when it cannot.
  virtual std::string ReadPiece(const std::string& hash, uint64_t offset, size_t maxBytes) const = 0;
};

// A worker that went away holding tasks (silent, gone, restarted, dropped): its tasks went
// back to the queue, counted by job.
struct WorkerLoss {
  std::string worker;  // its name
  std::string why;     // "went silent", "left", ...
  std::map<uint64_t, size_t> requeuedTasks;  // job id -> tasks of that job requeued
};

struct DispatcherCounters {
  uint64_t malformed = 0;         // undecodable or invalid messages dropped
  uint64_t unexpected = 0;        // valid messages that made no sense (unknown worker, wrong sizes)
  uint64_t duplicateResults = 0;  // results of tasks no longer outstanding (ignored)
  uint64_t foreignReplies = 0;    // RESULT or ERROR for a task in flight with another worker: dropped
  uint64_t workersDropped = 0;    // forgotten for a malformed RESULT of their own task
  uint64_t workersDistrusted = 0;  // found returning wrong values: banned, dropped
  uint64_t bannedReconnects = 0;   // READY from a banned principal on a new connection: ignored
  uint64_t tasksStranded = 0;      // checks no connected worker could take: to the referee
  uint64_t distrustedMessages = 0;  // messages from them afterwards: dropped
  uint64_t taskErrorsRetried = 0;  // a worker's ERROR: the task went back for a different worker
  uint64_t tasksFailed = 0;       // ERRORs from two different workers: the task failed
  uint64_t refusedKeys = 0;       // CURVE clients whose key is not on the allow-list
  uint64_t failedHandshakes = 0;  // connections refused before ZAP (no CURVE, wrong server key)
  uint64_t tasksSent = 0;
  uint64_t resultsReceived = 0;
  uint64_t pixelsReceived = 0;
  uint64_t requeued = 0;
  uint64_t workersLost = 0;
  uint64_t scenesSent = 0;
  uint64_t assetsSent = 0;  // whole assets sent to a worker
  uint64_t assetBytesSent = 0;
};

class Dispatcher {
 public:
  // Binds a ROUTER socket at `endpoint` ("tcp://*:5555", "tcp://127.0.0.1:0" for any port,
  // "ipc:///path"). Throws zmq::error_t if the address cannot be bound.
  // assets: where ASSET_GET is answered from; none: every asset request is refused.
  // curve: the coordinator's secret key and the worker allow-list; none: no authentication
  // (the caller keeps such an endpoint on loopback). Throws std::invalid_argument for keys
  // that cannot be used.
  Dispatcher(const std::string& endpoint, const Clock& clock, HeartbeatPolicy policy = {},
             const AssetSource* assets = nullptr, std::optional<CurveServerKeys> curve = std::nullopt);
  ~Dispatcher();

  std::string BoundEndpoint() const;
  // The CURVE public key workers must know (Z85), or "" without CURVE.
  const std::string& PublicKey() const { return publicKey_; }
  // ERRORs from this many different workers fail a task: one worker's may be its own fault.
  static constexpr size_t kWorkersThatMustFailATask = 2;

  // Jobs share the workers by priority, over the whole range -100..100: a job of priority
  // p >= 0 gets 1 + p shares, one of p < 0 gets 1 / (1 - p) (a job of 0 gets 51 tasks to
  // every one of a job of -50 while both have tasks waiting).
  static double WeightOf(int priority) { return TaskQueue::WeightOf(priority); }
  void AddJob(uint64_t jobId, int priority, uint32_t width, uint32_t height,
              const std::string& sceneHash, const std::string& sceneJson);
  // A running job's new priority counts from its next task on.
  void SetPriority(uint64_t jobId, int priority);
  // The workers lost since the last call, with the tasks of each job they held.
  std::vector<WorkerLoss> TakeWorkerLosses();
  // Drops the job's pending tasks and forgets its in-flight ones; late results are ignored.
  // When no job uses its scene any more, the workers that held its tasks are told so
  // (ERROR naming the scene): they drop the scene's tasks and give up building it.
  void RemoveJob(uint64_t jobId);
  void Enqueue(DispatchTask task);

  // Waits up to `timeout` for messages and handles all that arrived.
  void Receive(Milliseconds timeout, DispatchSink& sink);
  // Expires silent workers, sends heartbeats, hands pending tasks to workers with credit,
  // sends the next pieces of assets being fetched.
  void Flush();
  // Receive, then Flush.
  void Poll(Milliseconds timeout, DispatchSink& sink) {
    Receive(timeout, sink);
    Flush();
  }
  // Tells every worker the coordinator is leaving; destroying the dispatcher afterwards
  // waits (briefly, bounded) for the goodbyes to leave.
  void SayGoodbye();

  // A worker found returning wrong values (farm/exactness_audit.h): its principal is
  // banned. Every connection of it is dropped, its tasks go to others, and nothing it
  // sends is heard again, READY included, on this connection or any new one, until
  // Unban. False when it was banned already.
  bool Distrust(const std::string& principal, const std::string& why);
  // Bans kept from before (the job store's), applied before any worker is heard.
  void Ban(const std::string& principal) { banned_.insert(principal); }
  // Lifts a ban (an operator's decision); false when the principal was not banned.
  bool Unban(const std::string& principal) { return banned_.erase(principal) > 0; }
  // Pending tasks that may go to the referee (refereeMayTrace) and that no connected
  // worker may take, taken off the queue: the caller traces them elsewhere.
  std::vector<DispatchTask> TakeStranded();
  // A connected worker of the principal, or nullptr.
  const WorkerState* FindPrincipal(const std::string& principal) const;

  size_t PendingTasks() const { return queue_.Pending(); }
  size_t InFlightTasks() const { return queue_.InFlight(); }
  const WorkerRegistry& registry() const { return registry_; }
  const DispatcherCounters& counters() const { return counters_; }

 private:
  void ReceiveAll(DispatchSink& sink);
  void Handle(const std::string& identity, const wire::Peer& peer, wire::Message message, DispatchSink& sink);
  void OnReady(const std::string& identity, const wire::Peer& peer, const wire::Ready& ready);
  void OnResult(const std::string& identity, wire::Result&& result, DispatchSink& sink);
  void OnError(const std::string& identity, const wire::Error& error, DispatchSink& sink);
  // A RESULT or ERROR that names a task: false (and counted) unless `identity` holds it.
  bool IsHolder(const std::string& identity, uint64_t taskId);
  // Why the holder's result does not fit its task, or "" when it does.
  static std::string ResultMismatch(const DispatchTask& task, const wire::Result& result);
  // Forgets a worker that answered wrongly, tells it DISCONNECT, requeues its tasks.
  void DropWorker(const std::string& identity, const std::string& why);
  // Returns how many tasks of each job went back to the queue.
  std::map<uint64_t, size_t> Requeue(const std::vector<uint64_t>& taskIds);
  // A worker's tasks requeued because the worker is gone; noted for TakeWorkerLosses.
  void RequeueLost(const std::string& name, const std::string& why, const std::vector<uint64_t>& taskIds);
  // RequeueLost for a worker still in the registry: removes it first.
  void RemoveAndRequeue(const std::string& identity, const std::string& why);
  void SendHeartbeats(SteadyTime now);
  void OnAssetGet(const std::string& identity, const wire::AssetGet& get);
  void SendAssetPieces();
  void DispatchPending();
  bool AnyWorkerMayTake(const TaskQueue::Entry& entry) const;
  // False when the peer is gone or its queue is full.
  bool Send(const std::string& identity, const wire::Message& message);

  const Clock& clock_;
  HeartbeatPolicy policy_;
  zmq::context_t context_;
  // Declared between the context and the socket: it starts before the socket binds and
  // stops after it closes.
  std::unique_ptr<CurveAuthenticator> authenticator_;
  std::string publicKey_;
  zmq::socket_t socket_;
  std::set<std::string> banned_;      // principals never heard again (Distrust, Ban)
  std::set<std::string> distrusted_;  // connections of banned principals: never heard again
  WorkerRegistry registry_;
  TaskQueue queue_;
  std::map<std::string, std::string> scenes_;  // hash -> JSON, for the jobs present
  SteadyTime lastHeartbeat_;
  // When the socket was last read to the end. Workers are judged silent against it, not
  // against now: while the coordinator is busy (finishing a large frame) their messages
  // wait in the socket, and its own deafness is not their silence.
  SteadyTime lastDrained_;
  DispatcherCounters counters_;
  // Assets on their way to workers, sent a piece at a time, round robin, so that one large
  // texture neither blocks the loop on one read nor holds back tasks and heartbeats.
  struct AssetSend {
    std::string identity;
    std::string hash;
    uint64_t offset = 0;
    uint64_t totalSize = 0;
  };
  const AssetSource* assets_;
  std::deque<AssetSend> assetSends_;
  std::vector<WorkerLoss> losses_;
};

}  // namespace tcfarm
