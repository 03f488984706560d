#include "proto/net/http_listener.h"

#include <stdexcept>

#include <sys/socket.h>

namespace tcfarm {

void GrowingThreadPool::enqueue(std::function<void()> task) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_) return;
  tasks_.push_back(std::move(task));
  // Every waiting task needs an idle thread of its own: one woken thread per task.
  if (tasks_.size() > idle_ && threads_.size() < maxThreads_) {
    threads_.emplace_back([this] { Work(); });
  } else {
    wake_.notify_one();
  }
}

void GrowingThreadPool::shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ && threads_.empty()) return;
    stopping_ = true;
  }
  wake_.notify_all();
  // No thread is started once stopping_ is set, so the list no longer changes.
  for (std::thread& thread : threads_) {
    if (thread.joinable()) thread.join();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  threads_.clear();
}

size_t GrowingThreadPool::threads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return threads_.size();
}

void GrowingThreadPool::Work() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    ++idle_;
    wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
    --idle_;
    if (tasks_.empty()) return;  // stopping, nothing left to run
    std::function<void()> task = std::move(tasks_.front());
    tasks_.pop_front();
    lock.unlock();
    task();
    lock.lock();
  }
}

int HttpListener::Start(std::unique_ptr<httplib::Server> server, const std::string& host, int port) {
  if (server_) throw std::logic_error("HttpListener::Start: already started");
  if (dynamic_cast<ConnectionGuard*>(server.get()) == nullptr) {
    throw std::logic_error("HttpListener::Start: expected a GuardedServer or GuardedTlsServer, whose requests are bounded");
  }
  // httplib's default sets SO_REUSEPORT, with which a second process on the same port
  // would silently share it instead of failing to start. The callback also sees the
  // listening socket, whose backlog is raised once it is bound.
  auto listening = std::make_shared<socket_t>(INVALID_SOCKET);
  server->set_socket_options([listening](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, reinterpret_cast<const char*>(&yes), sizeof yes);
    *listening = sock;
  });
  server->set_read_timeout(kReadTimeout);
  server->set_write_timeout(kWriteTimeout);
  server->set_keep_alive_timeout(kKeepAliveTimeout.count());
  // Answers at once on every keep-alive request (GuardedConnection sets it on each
  // connection; this is the listening socket's).
  server->set_tcp_nodelay(true);
  server->new_task_queue = [] { return new GrowingThreadPool(kMaxThreads); };
  int bound = port;
  if (port == 0) {
    bound = server->bind_to_any_port(host);
  } else if (!server->bind_to_port(host, port)) {
    bound = -1;
  }
  if (bound < 0) throw std::runtime_error("cannot listen on " + host + ":" + std::to_string(port));
  // httplib listens with a backlog of 5; listening again on a listening socket only
  // changes its backlog (Linux, BSD).
  if (*listening != INVALID_SOCKET) ::listen(*listening, kListenBacklog);
  server_ = std::move(server);
  listenReturned_ = false;
  thread_ = std::thread([this] {
    server_->listen_after_bind();
    listenReturned_ = true;
  });
  // httplib's stop() does nothing until the listen loop is running, so Stop right after
  // Start would otherwise hang in join.
  while (!server_->is_running() && !listenReturned_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return bound;
}

void HttpListener::Stop() {
  if (!server_) return;
  server_->stop();
  if (thread_.joinable()) thread_.join();
  server_.reset();
}

}  // namespace tcfarm
