// A cpp-httplib server listening on its own thread: the coordinator's API and a worker's
// /metrics both serve this way. Start returns once requests can be served; Stop (or the
// destructor) returns once the listen loop has ended.
//
// Slow or many clients cannot stall it: every connection has read and write timeouts, the
// listen backlog holds bursts of connections, and requests run on a pool that grows with
// the connections open (up to kMaxThreads), since httplib gives each connection one thread
// for as long as it stays open, an idle or trickling one included. Large or endless
// requests cannot fill its memory: it serves only a GuardedServer or GuardedTlsServer
// (net/guarded_server.h), which bound every request before httplib reads it.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "proto/net/guarded_server.h"

namespace tcfarm {

// httplib's TaskQueue with a thread for every connection at once, up to a limit: its own
// ThreadPool has a fixed size (8 on a small machine), so 8 idle connections held every
// other client waiting. Threads are started when more tasks wait than threads are idle,
// and kept for the next burst; beyond the limit tasks wait their turn.
class GrowingThreadPool : public httplib::TaskQueue {
 public:
  explicit GrowingThreadPool(size_t maxThreads) : maxThreads_(maxThreads) {}
  ~GrowingThreadPool() override { shutdown(); }

  void enqueue(std::function<void()> task) override;
  void shutdown() override;  // runs the tasks queued, then joins every thread
  size_t threads() const;

 private:
  void Work();

  const size_t maxThreads_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> tasks_;
  std::vector<std::thread> threads_;
  size_t idle_ = 0;
  bool stopping_ = false;
};

class HttpListener {
 public:
  // A connection silent this long while a request is expected or read is closed; so is a
  // client that takes no bytes of a response for as long.
  static constexpr std::chrono::seconds kReadTimeout{5};
  static constexpr std::chrono::seconds kWriteTimeout{5};
  // An idle keep-alive connection holds a thread; it is closed after this much silence.
  static constexpr std::chrono::seconds kKeepAliveTimeout{5};
  // Connections accepted at once: one thread each. Trickling clients (a byte a second
  // never trips a read timeout) each keep one until they finish.
  static constexpr size_t kMaxThreads = 512;
  // Connections the kernel queues before they are accepted; httplib's own is 5, so a burst
  // of clients got connection resets. Linux caps it at net.core.somaxconn.
  static constexpr int kListenBacklog = 1024;

  HttpListener() = default;
  HttpListener(const HttpListener&) = delete;
  HttpListener& operator=(const HttpListener&) = delete;
  ~HttpListener() { Stop(); }

  // Binds host:port (port 0: any free port) and serves `server` on a new thread. Returns
  // the port bound; throws std::runtime_error naming the address when it cannot listen,
  // std::logic_error when `server` is not a ConnectionGuard.
  int Start(std::unique_ptr<httplib::Server> server, const std::string& host, int port);
  void Stop();
  bool running() const { return server_ != nullptr; }

 private:
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::atomic<bool> listenReturned_{false};
};

}  // namespace tcfarm
