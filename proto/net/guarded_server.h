// httplib's Server and SSLServer, each connection served through a GuardedConnection
// (net/guarded_connection.h), and every request passed through a gate before httplib reads
// any of its body. In httplib 0.11.4 (Server::routing, read_content):
//
// - PRI has no route, yet its body is read whole into Request::body, and without a
//   Content-Length it is read until the client stops sending: an anonymous
//   "PRI / HTTP/1.1" followed by 1.5 GB grew the coordinator by as much.
// - GET, HEAD and OPTIONS bodies, and a DELETE body without a Content-Length, are not read
//   at all: their bytes were then read as the next request's line, which grows unbounded.
// - A Content-Length over the payload limit is read (and dropped) to its end before the
//   413, and a Transfer-Encoding other than chunked is read until the client closes.
// - Expect: 100-continue is answered 100 before any handler has seen the request.
//
// The gate runs as httplib's pre-routing handler and as its 100-continue handler, so on
// the request line and headers alone: a method httplib does not route gets 501, a body
// larger than its route takes (BodyLimit; without one, no request may have a body) 413, an unclear
// framing (Content-Length with Transfer-Encoding, a Content-Length that is not a number, a
// coding other than chunked) 400 or 501; each then closes the connection with the body
// unread. A body httplib will not read closes the connection after the response. A method
// httplib cannot parse (FOO) gets its 400, made a 501 by LibraryStatus in the error handler,
// and the connection closes because the head was never read whole.
//
// Both classes own their pre-routing and 100-continue handlers: setting others would
// remove the gate.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>

#include <httplib.h>

#include "proto/net/guarded_connection.h"

namespace tcfarm {

// The methods httplib routes to handlers; any other gets 501.
bool IsRoutedMethod(std::string_view method);

// The gate and the connection loop both server classes share.
class ConnectionGuard {
 public:
  // The largest body a request's route takes, from its method and path; 0: none at all
  // (a chunked body too is then refused, its size being unknown until it is read).
  using BodyLimit = std::function<uint64_t(const httplib::Request& request)>;

  virtual ~ConnectionGuard() = default;
  void set_body_limit(BodyLimit limit) { bodyLimit_ = std::move(limit); }

  // The status httplib answered with, or 501 for a request whose method it cannot parse
  // (it says 400): for an error handler.
  static int LibraryStatus(const httplib::Request& request, int status);

 protected:
  struct Settings {
    ConnectionTimeouts timeouts;
    size_t keepAliveMaxCount;
  };
  using ProcessRequest = std::function<bool(httplib::Stream& stream, bool closeConnection, bool& connectionClosed)>;

  static Settings MakeSettings(time_t readSeconds, time_t readMicroseconds, time_t writeSeconds,
                               time_t writeMicroseconds, time_t keepAliveSeconds, size_t keepAliveMaxCount);
  // The gate as the server's pre-routing and 100-continue handlers, and LibraryStatus as
  // its error handler until another is set.
  void InstallGate(httplib::Server& server);
  // Serves requests on the connection until it ends, as httplib's keep-alive loop does;
  // false when the last request failed.
  static bool Serve(GuardedConnection& connection, const Settings& settings, const std::function<bool()>& serving,
                    const ProcessRequest& process);
  // Closes the socket; a connection that leaves a body unread first takes (and drops) what
  // the client still sends, for a second at most, so that the client reads the answer
  // instead of a reset.
  static void Close(socket_t sock, bool bodyLeftUnread);

 private:
  // The status refusing the request, or nullopt to let it through.
  std::optional<int> Refusal(const httplib::Request& request) const;

  BodyLimit bodyLimit_;
};

class GuardedServer : public httplib::Server, public ConnectionGuard {
 public:
  GuardedServer();

 private:
  bool process_and_close_socket(socket_t sock) override;
  Settings CurrentSettings() const;
};

class GuardedTlsServer : public httplib::SSLServer, public ConnectionGuard {
 public:
  GuardedTlsServer(const char* certFile, const char* keyFile);

 private:
  bool process_and_close_socket(socket_t sock) override;
  Settings CurrentSettings() const;
};

}  // namespace tcfarm
