#include "proto/net/guarded_server.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <climits>
#include <string>

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace tcfarm {
namespace {

using httplib::Request;
using httplib::Response;
using HandlerResponse = httplib::Server::HandlerResponse;

// What a connection closed with a body unread still takes from the client before it
// closes, so the client finishes sending and reads the answer instead of a reset.
constexpr size_t kLingerBytes = 16u << 20;
constexpr std::chrono::milliseconds kLingerTime{1000};
constexpr size_t kMaxLengthDigits = 19;  // every 19-digit number fits in uint64_t

bool EqualIgnoringCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](unsigned char x, unsigned char y) {
           return std::tolower(x) == std::tolower(y);
         });
}

// Whether httplib reads the body the request declares (Server::routing,
// read_content_core): it leaves a DELETE's unread without a Content-Length.
bool LibraryReadsBody(const Request& request) {
  return request.method == "POST" || request.method == "PUT" || request.method == "PATCH" ||
         (request.method == "DELETE" && request.has_header("Content-Length"));
}

bool DeclaresBody(const Request& request) {
  return request.has_header("Transfer-Encoding") ||
         (request.has_header("Content-Length") && request.get_header_value("Content-Length") != "0");
}

void CloseAfterResponse() {
  if (GuardedConnection* connection = GuardedConnection::Current()) connection->CloseAfterResponse();
}

class SocketTransport final : public Transport {
 public:
  explicit SocketTransport(socket_t sock) : sock_(sock) {}
  ssize_t Receive(char* data, size_t size) override {
    ssize_t got = 0;
    do {
      got = recv(sock_, data, size, 0);
    } while (got < 0 && errno == EINTR);
    return got;
  }
  ssize_t Send(const char* data, size_t size) override {
    ssize_t sent = 0;
    do {
      sent = send(sock_, data, size, MSG_NOSIGNAL);
    } while (sent < 0 && errno == EINTR);
    return sent;
  }

 private:
  const socket_t sock_;
};

// A TLS session on the accepted socket. The socket blocks, with the read and write
// timeouts httplib set on it when it accepted it, so the handshake and every record
// are bounded in time as the plain socket's reads are.
class TlsTransport final : public Transport {
 public:
  TlsTransport(socket_t sock, SSL_CTX* context) : ssl_(SSL_new(context)) {
    accepted_ = ssl_ != nullptr && SSL_set_fd(ssl_, sock) == 1 && SSL_accept(ssl_) == 1;
  }
  ~TlsTransport() override {
    if (ssl_ == nullptr) return;
    if (accepted_ && closeCleanly_) SSL_shutdown(ssl_);
    SSL_free(ssl_);
  }
  TlsTransport(const TlsTransport&) = delete;
  TlsTransport& operator=(const TlsTransport&) = delete;

  bool accepted() const { return accepted_; }
  SSL* ssl() const { return ssl_; }
  void CloseCleanly(bool clean) { closeCleanly_ = clean; }

  ssize_t Receive(char* data, size_t size) override {
    const int got = SSL_read(ssl_, data, static_cast<int>(std::min<size_t>(size, INT_MAX)));
    if (got > 0) return got;
    return SSL_get_error(ssl_, got) == SSL_ERROR_ZERO_RETURN ? 0 : -1;
  }
  ssize_t Send(const char* data, size_t size) override {
    const int sent = SSL_write(ssl_, data, static_cast<int>(std::min<size_t>(size, INT_MAX)));
    return sent > 0 ? sent : -1;
  }
  bool HasPending() const override { return SSL_pending(ssl_) > 0; }

 private:
  SSL* const ssl_;
  bool accepted_ = false;
  bool closeCleanly_ = true;
};

}  // namespace

bool IsRoutedMethod(std::string_view method) {
  for (std::string_view routed : {"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"}) {
    if (method == routed) return true;
  }
  return false;
}

int ConnectionGuard::LibraryStatus(const Request& request, int status) {
  // httplib refuses a request line whose method it does not know with 400 (and has set
  // Request::method from it); a word of capitals there is a method, which 501 names.
  const bool methodWord = !request.method.empty() && std::all_of(request.method.begin(), request.method.end(),
                                                                 [](unsigned char c) { return std::isupper(c); });
  return status == 400 && methodWord && !IsRoutedMethod(request.method) ? 501 : status;
}

std::optional<int> ConnectionGuard::Refusal(const Request& request) const {
  if (!IsRoutedMethod(request.method)) return 501;
  const size_t lengths = request.get_header_value_count("Content-Length");
  const size_t codings = request.get_header_value_count("Transfer-Encoding");
  // Two framings, or one given twice, may be read differently by a proxy in front (request
  // smuggling): RFC 9112 section 6.3 says to refuse them.
  if (lengths + codings > 1) return 400;
  if (codings == 1 && !EqualIgnoringCase(request.get_header_value("Transfer-Encoding"), "chunked")) return 501;
  uint64_t length = 0;
  if (lengths == 1) {
    const std::string text = request.get_header_value("Content-Length");
    if (text.empty() || text.size() > kMaxLengthDigits ||
        !std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); })) {
      return 400;
    }
    length = std::stoull(text);
  }
  const uint64_t limit = bodyLimit_ ? bodyLimit_(request) : 0;
  if (length > limit || (limit == 0 && codings == 1)) return 413;
  return std::nullopt;
}

void ConnectionGuard::InstallGate(httplib::Server& server) {
  server.set_pre_routing_handler([this](const Request& request, Response& response) {
    if (const std::optional<int> status = Refusal(request)) {
      response.status = *status;
      CloseAfterResponse();
      return HandlerResponse::Handled;
    }
    // A body httplib leaves unread would be read as the next request.
    if (DeclaresBody(request) && !LibraryReadsBody(request)) CloseAfterResponse();
    return HandlerResponse::Unhandled;
  });
  // httplib answers "100 Continue" before routing; a request the gate refuses gets its
  // refusal instead, and the client never sends the body.
  server.set_expect_100_continue_handler([this](const Request& request, Response& response) {
    const std::optional<int> status = Refusal(request);
    if (!status) return 100;
    CloseAfterResponse();
    response.status = *status;  // httplib answers with the response, not the value returned
    return *status;
  });
  server.set_error_handler([](const Request& request, Response& response) {
    response.status = LibraryStatus(request, response.status);
  });
}

ConnectionGuard::Settings ConnectionGuard::MakeSettings(time_t readSeconds, time_t readMicroseconds,
                                                        time_t writeSeconds, time_t writeMicroseconds,
                                                        time_t keepAliveSeconds, size_t keepAliveMaxCount) {
  using std::chrono::microseconds;
  using std::chrono::seconds;
  return Settings{{seconds(readSeconds) + microseconds(readMicroseconds),
                   seconds(writeSeconds) + microseconds(writeMicroseconds), seconds(keepAliveSeconds)},
                  keepAliveMaxCount};
}

// httplib's keep-alive loop (process_server_socket_core), on a GuardedConnection, ending
// also when the connection is to close or a request's head was not read whole.
bool ConnectionGuard::Serve(GuardedConnection& connection, const Settings& settings,
                            const std::function<bool()>& serving, const ProcessRequest& process) {
  bool ok = false;
  for (size_t left = settings.keepAliveMaxCount; left > 0 && connection.AwaitRequest(serving); --left) {
    connection.BeginRequest();
    bool connectionClosed = false;
    ok = process(connection, left == 1, connectionClosed);
    if (!ok || connectionClosed || connection.closing() || !connection.headComplete()) break;
  }
  return ok;
}

void ConnectionGuard::Close(socket_t sock, bool bodyLeftUnread) {
  if (bodyLeftUnread) {
    shutdown(sock, SHUT_WR);
    const auto deadline = std::chrono::steady_clock::now() + kLingerTime;
    char drop[16384];
    for (size_t dropped = 0; dropped < kLingerBytes;) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      pollfd waiting{sock, POLLIN, 0};
      if (left.count() <= 0 || poll(&waiting, 1, static_cast<int>(left.count())) <= 0) break;
      const ssize_t got = recv(sock, drop, sizeof drop, 0);
      if (got <= 0) break;
      dropped += static_cast<size_t>(got);
    }
  }
  shutdown(sock, SHUT_RDWR);
  close(sock);
}

GuardedServer::GuardedServer() {
  set_tcp_nodelay(true);
  InstallGate(*this);
}

ConnectionGuard::Settings GuardedServer::CurrentSettings() const {
  return MakeSettings(read_timeout_sec_, read_timeout_usec_, write_timeout_sec_, write_timeout_usec_,
                      keep_alive_timeout_sec_, keep_alive_max_count_);
}

bool GuardedServer::process_and_close_socket(socket_t sock) {
  const Settings settings = CurrentSettings();
  SocketTransport transport(sock);
  bool ok = false;
  bool unread = false;
  {
    GuardedConnection connection(sock, transport, settings.timeouts);
    ok = Serve(
        connection, settings, [this] { return svr_sock_ != INVALID_SOCKET; },
        [this](httplib::Stream& stream, bool closeConnection, bool& connectionClosed) {
          return process_request(stream, closeConnection, connectionClosed, nullptr);
        });
    unread = connection.leavesBytesUnread();
  }
  Close(sock, unread);
  return ok;
}

GuardedTlsServer::GuardedTlsServer(const char* certFile, const char* keyFile) : SSLServer(certFile, keyFile) {
  set_tcp_nodelay(true);
  InstallGate(*this);
}

ConnectionGuard::Settings GuardedTlsServer::CurrentSettings() const {
  return MakeSettings(read_timeout_sec_, read_timeout_usec_, write_timeout_sec_, write_timeout_usec_,
                      keep_alive_timeout_sec_, keep_alive_max_count_);
}

bool GuardedTlsServer::process_and_close_socket(socket_t sock) {
  const Settings settings = CurrentSettings();
  bool ok = false;
  bool unread = false;
  {
    TlsTransport transport(sock, ssl_context());
    if (transport.accepted()) {
      GuardedConnection connection(sock, transport, settings.timeouts);
      ok = Serve(
          connection, settings, [this] { return svr_sock_ != INVALID_SOCKET; },
          [this, &transport](httplib::Stream& stream, bool closeConnection, bool& connectionClosed) {
            return process_request(stream, closeConnection, connectionClosed,
                                   [&transport](Request& request) { request.ssl = transport.ssl(); });
          });
      unread = connection.leavesBytesUnread();
    }
    // As httplib does: a close_notify only after a session that ended well.
    transport.CloseCleanly(ok);
  }
  Close(sock, unread);
  return ok;
}

}  // namespace tcfarm
