// A cpp-httplib server listening on its own thread: the coordinator's API and a worker's
// /metrics both serve this way. Start returns once requests can be served; Stop (or the
// destructor) returns once the listen loop has ended.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include <httplib.h>

namespace tcfarm {

class HttpListener {
 public:
  HttpListener() = default;
  HttpListener(const HttpListener&) = delete;
  HttpListener& operator=(const HttpListener&) = delete;
  ~HttpListener() { Stop(); }

  // Binds host:port (port 0: any free port) and serves `server` on a new thread. Returns
  // the port bound; throws std::runtime_error naming the address when it cannot listen.
  int Start(std::unique_ptr<httplib::Server> server, const std::string& host, int port);
  void Stop();
  bool running() const { return server_ != nullptr; }

 private:
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::atomic<bool> listenReturned_{false};
};

}  // namespace tcfarm
