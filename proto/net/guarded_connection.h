// One HTTP connection as httplib's server reads and writes it (an httplib::Stream), with
// the bounds httplib 0.11.4 lacks, and what a handler needs to see of the connection:
//
// - Memory: httplib reads a request's line and its headers a byte at a time into a line
//   buffer that grows without end (stream_line_reader), and keeps every header line it
//   reads, so a client sending bytes without a newline, or headers without end, filled the
//   coordinator's memory before any route or token check ran. Here a line read this way
//   may hold kMaxLineBytes, a request's head kMaxHeadBytes; past either the read fails and
//   the connection is closed.
// - The bytes as sent: httplib percent-decodes every header value (parse_header calls
//   decode_url), so "Bearer TOK%45N" reached the handlers as "Bearer TOKEN" and a %00 cut
//   a value short. rawHead() keeps the request line and headers exactly as received, and
//   RawHeaderValues reads a header from them the way httplib splits them.
// - Closing: CloseAfterResponse ends the connection once the current response is written,
//   for a request whose body is refused unread (its bytes must never be taken for the next
//   request); reads fail from then on.
// - Latency: the socket has TCP_NODELAY. httplib writes a response's head and its body
//   separately, so with Nagle's algorithm the body of each keep-alive request after the
//   first waited for the client's delayed ACK (about 40 ms).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <httplib.h>

namespace tcfarm {

// How a connection's bytes cross: a plain socket or a TLS session on it.
class Transport {
 public:
  virtual ~Transport() = default;
  // Up to size bytes: > 0 read, 0 at the end of the stream, < 0 on an error or a timeout.
  virtual ssize_t Receive(char* data, size_t size) = 0;
  virtual ssize_t Send(const char* data, size_t size) = 0;
  // Bytes already received (decrypted TLS records) that need no wait on the socket.
  virtual bool HasPending() const { return false; }
};

struct ConnectionTimeouts {
  std::chrono::microseconds read;
  std::chrono::microseconds write;
  std::chrono::microseconds keepAlive;  // an idle connection waits this long for a request
};

class GuardedConnection final : public httplib::Stream {
 public:
  // httplib's own limits on a header line and the request URI are 8 KiB; a line longer
  // than this is never a request's.
  static constexpr size_t kMaxLineBytes = 16u << 10;
  // The request line and every header together.
  static constexpr size_t kMaxHeadBytes = 64u << 10;

  // Sets TCP_NODELAY on sock; the calling thread serves this connection until it is
  // destroyed (Current).
  GuardedConnection(socket_t sock, Transport& transport, ConnectionTimeouts timeouts);
  ~GuardedConnection() override;
  GuardedConnection(const GuardedConnection&) = delete;
  GuardedConnection& operator=(const GuardedConnection&) = delete;

  // The connection the calling thread is serving, or null: httplib runs a request's
  // handlers on the thread that reads it.
  static GuardedConnection* Current();

  // Waits for the next request's first byte, up to the keep-alive timeout; false when
  // none comes, the client has gone or `serving` turns false (checked every 100 ms).
  bool AwaitRequest(const std::function<bool()>& serving);
  // Starts a new request's head: what rawHead() holds and the limits count from here.
  void BeginRequest();
  void CloseAfterResponse() { closing_ = true; }
  bool closing() const { return closing_; }
  // The request line and headers as received, through the blank line once headComplete().
  const std::string& rawHead() const { return rawHead_; }
  bool headComplete() const { return headComplete_; }
  // Whether the client may have sent bytes no request took (a body refused unread, a head
  // cut off): closing then first drains them, so that the client sees the answer.
  bool leavesBytesUnread() const { return closing_ || (!headComplete_ && !rawHead_.empty()); }

  bool is_readable() const override;
  bool is_writable() const override;
  ssize_t read(char* ptr, size_t size) override;
  ssize_t write(const char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override;
  void get_local_ip_and_port(std::string& ip, int& port) const override;
  socket_t socket() const override { return sock_; }

 private:
  bool Wait(short events, std::chrono::microseconds timeout) const;
  // Counts bytes handed to httplib against the limits; false (and closing) past one.
  bool Account(const char* data, size_t size);

  const socket_t sock_;
  Transport& transport_;
  const ConnectionTimeouts timeouts_;
  std::array<char, 16384> buffer_{};
  size_t begin_ = 0;  // buffer_[begin_, end_) is received, not yet read
  size_t end_ = 0;
  std::string rawHead_;
  bool headComplete_ = false;
  size_t lineBytes_ = 0;  // bytes read one at a time since the last newline
  bool closing_ = false;
};

// The values of header `name` (case-insensitive) in a raw request head, each exactly as
// sent but for the spaces and tabs around it, split as httplib splits them: lines after
// the request line up to the blank line, only those ending in CRLF, an empty value none.
std::vector<std::string> RawHeaderValues(std::string_view head, std::string_view name);

}  // namespace tcfarm
