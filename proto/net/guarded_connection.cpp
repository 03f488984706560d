#include "proto/net/guarded_connection.h"

#include <algorithm>
#include <cctype>
#include <cstring>

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>

namespace tcfarm {
namespace {

thread_local GuardedConnection* current = nullptr;

constexpr std::chrono::milliseconds kServingCheck{100};

int PollMilliseconds(std::chrono::microseconds timeout) {
  return static_cast<int>(std::max<int64_t>(0, (timeout.count() + 999) / 1000));
}

void AddressOf(bool peer, socket_t sock, std::string& ip, int& port) {
  sockaddr_storage address{};
  socklen_t length = sizeof address;
  const int got = peer ? getpeername(sock, reinterpret_cast<sockaddr*>(&address), &length)
                       : getsockname(sock, reinterpret_cast<sockaddr*>(&address), &length);
  if (got != 0) return;
  char host[NI_MAXHOST];
  char service[NI_MAXSERV];
  if (getnameinfo(reinterpret_cast<sockaddr*>(&address), length, host, sizeof host, service, sizeof service,
                  NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(service);
  }
}

bool EqualIgnoringCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](unsigned char x, unsigned char y) {
           return std::tolower(x) == std::tolower(y);
         });
}

bool IsSpaceOrTab(char c) { return c == ' ' || c == '\t'; }

}  // namespace

GuardedConnection::GuardedConnection(socket_t sock, Transport& transport, ConnectionTimeouts timeouts)
    : sock_(sock), transport_(transport), timeouts_(timeouts) {
  int yes = 1;
  setsockopt(sock_, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
  current = this;
}

GuardedConnection::~GuardedConnection() {
  if (current == this) current = nullptr;
}

GuardedConnection* GuardedConnection::Current() { return current; }

bool GuardedConnection::AwaitRequest(const std::function<bool()>& serving) {
  if (begin_ < end_ || transport_.HasPending()) return true;
  const auto deadline = std::chrono::steady_clock::now() + timeouts_.keepAlive;
  while (serving()) {
    const auto left = std::chrono::duration_cast<std::chrono::microseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd waiting{sock_, POLLIN, 0};
    const int ready = poll(&waiting, 1, PollMilliseconds(std::min<std::chrono::microseconds>(left, kServingCheck)));
    if (ready < 0 && errno != EINTR) return false;
    if (ready > 0) return (waiting.revents & (POLLIN | POLLHUP)) != 0;
  }
  return false;
}

void GuardedConnection::BeginRequest() {
  rawHead_.clear();
  headComplete_ = false;
  lineBytes_ = 0;
}

bool GuardedConnection::Wait(short events, std::chrono::microseconds timeout) const {
  pollfd waiting{sock_, events, 0};
  int ready = 0;
  do {
    ready = poll(&waiting, 1, PollMilliseconds(timeout));
  } while (ready < 0 && errno == EINTR);
  return ready > 0;
}

bool GuardedConnection::is_readable() const {
  return begin_ < end_ || transport_.HasPending() || Wait(POLLIN, timeouts_.read);
}

// As httplib's SocketStream: writable and not closed by the client. Every write asks, so
// that a response that only writes (an event stream) ends once its client has gone.
bool GuardedConnection::is_writable() const {
  if (!Wait(POLLOUT, timeouts_.write)) return false;
  if (!Wait(POLLIN, std::chrono::microseconds(0))) return true;
  char peek = 0;
  return recv(sock_, &peek, 1, MSG_PEEK) > 0;
}

ssize_t GuardedConnection::read(char* ptr, size_t size) {
  if (closing_) return -1;
  if (begin_ == end_) {
    if (!transport_.HasPending() && !Wait(POLLIN, timeouts_.read)) return -1;
    const ssize_t got = transport_.Receive(buffer_.data(), buffer_.size());
    if (got <= 0) return got;
    begin_ = 0;
    end_ = static_cast<size_t>(got);
  }
  const size_t count = std::min(size, end_ - begin_);
  if (!Account(buffer_.data() + begin_, count)) return -1;
  std::memcpy(ptr, buffer_.data() + begin_, count);
  begin_ += count;
  return static_cast<ssize_t>(count);
}

// httplib 0.11.4 reads every line (request line, headers, chunk sizes, trailers) through
// stream_line_reader, one byte per read(); bodies it reads in blocks. So a run of one-byte
// reads without a newline is one line, and until the blank line every byte is the head.
bool GuardedConnection::Account(const char* data, size_t size) {
  if (!headComplete_) {
    rawHead_.append(data, size);
    // The head ends with a line that is only CRLF (httplib skips lines ending in a bare LF).
    headComplete_ = rawHead_.size() >= 3 && rawHead_.compare(rawHead_.size() - 3, 3, "\n\r\n") == 0;
    if (rawHead_.size() > kMaxHeadBytes) {
      closing_ = true;
      return false;
    }
  }
  if (size != 1) {
    lineBytes_ = 0;
  } else if (*data == '\n') {
    lineBytes_ = 0;
  } else if (++lineBytes_ > kMaxLineBytes) {
    closing_ = true;
    return false;
  }
  return true;
}

ssize_t GuardedConnection::write(const char* ptr, size_t size) {
  if (!is_writable()) return -1;
  return transport_.Send(ptr, size);
}

void GuardedConnection::get_remote_ip_and_port(std::string& ip, int& port) const { AddressOf(true, sock_, ip, port); }

void GuardedConnection::get_local_ip_and_port(std::string& ip, int& port) const { AddressOf(false, sock_, ip, port); }

std::vector<std::string> RawHeaderValues(std::string_view head, std::string_view name) {
  std::vector<std::string> values;
  size_t begin = head.find('\n');  // past the request line
  while (begin != std::string_view::npos && ++begin < head.size()) {
    const size_t newline = head.find('\n', begin);
    if (newline == std::string_view::npos) break;
    std::string_view line = head.substr(begin, newline - begin);
    begin = newline;
    if (line.empty() || line.back() != '\r') continue;  // httplib skips a line without CRLF
    line.remove_suffix(1);
    if (line.empty()) break;  // the blank line: the end of the head
    while (!line.empty() && IsSpaceOrTab(line.back())) line.remove_suffix(1);
    const size_t colon = line.find(':');
    if (colon == std::string_view::npos || !EqualIgnoringCase(line.substr(0, colon), name)) continue;
    std::string_view value = line.substr(colon + 1);
    while (!value.empty() && IsSpaceOrTab(value.front())) value.remove_prefix(1);
    if (!value.empty()) values.emplace_back(value);
  }
  return values;
}

}  // namespace tcfarm
