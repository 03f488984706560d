#include "net/http_listener.h"

#include <chrono>
#include <stdexcept>

namespace tcfarm {

int HttpListener::Start(std::unique_ptr<httplib::Server> server, const std::string& host, int port) {
  if (server_) throw std::logic_error("HttpListener::Start: already started");
  // httplib's default sets SO_REUSEPORT, with which a second process on the same port
  // would silently share it instead of failing to start.
  server->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, reinterpret_cast<const char*>(&yes), sizeof yes);
  });
  int bound = port;
  if (port == 0) {
    bound = server->bind_to_any_port(host);
  } else if (!server->bind_to_port(host, port)) {
    bound = -1;
  }
  if (bound < 0) throw std::runtime_error("cannot listen on " + host + ":" + std::to_string(port));
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
