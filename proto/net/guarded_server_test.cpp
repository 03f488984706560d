// GuardedServer through HttpListener on a free port, spoken to over real sockets: the
// gate's answers, the connection's limits and options, and the raw header parsing.
#include "proto/net/guarded_server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "proto/net/http_listener.h"

namespace tcfarm {
namespace {

constexpr uint64_t kBodyLimit = 1024;

class Socket {
 public:
  explicit Socket(int port) : fd_(socket(AF_INET, SOCK_STREAM, 0)) {
    timeval timeout{5, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(port));
    inet_pton(AF_INET, "127.0.0.1", &address.sin_addr);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  ~Socket() { close(fd_); }
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;

  bool connected() const { return connected_; }
  bool Send(const std::string& bytes) {
    return send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size());
  }
  // Sends up to `total` bytes of `fill` in blocks; returns how many went before the server
  // closed the connection (or all of them).
  uint64_t SendUpTo(uint64_t total, char fill) {
    const std::string block(1 << 16, fill);
    uint64_t sent = 0;
    while (sent < total) {
      const ssize_t n = send(fd_, block.data(), std::min<uint64_t>(block.size(), total - sent), MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<uint64_t>(n);
    }
    return sent;
  }
  // Everything the server sends until it closes the connection (or 5 s of silence).
  std::string ReadToEnd() {
    std::string answer;
    char buffer[4096];
    ssize_t got = 0;
    while ((got = recv(fd_, buffer, sizeof buffer, 0)) > 0) answer.append(buffer, static_cast<size_t>(got));
    closedByServer_ = got == 0 || errno == ECONNRESET;
    return answer;
  }
  // One response whose body is `Content-Length` long, leaving the connection open.
  std::string ReadResponse() {
    std::string answer;
    char byte = 0;
    while (answer.find("\r\n\r\n") == std::string::npos && recv(fd_, &byte, 1, 0) == 1) answer += byte;
    const size_t length = answer.find("Content-Length: ");
    size_t left = length == std::string::npos ? 0 : std::stoul(answer.substr(length + 16));
    while (left > 0 && recv(fd_, &byte, 1, 0) == 1) {
      answer += byte;
      --left;
    }
    return answer;
  }
  bool closedByServer() const { return closedByServer_; }

 private:
  int fd_;
  bool connected_ = false;
  bool closedByServer_ = false;
};

std::string StatusLine(const std::string& response) { return response.substr(0, response.find("\r\n")); }

class GuardedServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto server = std::make_unique<GuardedServer>();
    server->set_body_limit([](const httplib::Request&) { return kBodyLimit; });
    server->Get("/hello", [](const httplib::Request&, httplib::Response& response) {
      response.set_content("hello", "text/plain");
    });
    // What the option is on the connection this request came on, seen from the server.
    server->Get("/nodelay", [](const httplib::Request&, httplib::Response& response) {
      int value = -1;
      socklen_t length = sizeof value;
      const GuardedConnection* connection = GuardedConnection::Current();
      if (connection == nullptr ||
          getsockopt(connection->socket(), IPPROTO_TCP, TCP_NODELAY, &value, &length) != 0) {
        value = -1;
      }
      response.set_content(std::to_string(value), "text/plain");
    });
    server->Post("/echo", [](const httplib::Request&, httplib::Response& response,
                             const httplib::ContentReader& reader) {
      std::string body;
      reader([&body](const char* data, size_t length) {
        body.append(data, length);
        return true;
      });
      response.set_content(body, "text/plain");
    });
    port_ = listener_.Start(std::move(server), "127.0.0.1", 0);
  }

  // Sends a request and everything the server answers until it closes the connection.
  std::string Exchange(const std::string& request, bool* closed = nullptr) {
    Socket socket(port_);
    EXPECT_TRUE(socket.connected());
    EXPECT_TRUE(socket.Send(request));
    const std::string answer = socket.ReadToEnd();
    if (closed != nullptr) *closed = socket.closedByServer();
    return answer;
  }

  HttpListener listener_;
  int port_ = 0;
};

TEST_F(GuardedServerTest, EveryConnectionHasTcpNoDelay) {
  httplib::Client client("127.0.0.1", port_);
  client.set_keep_alive(true);
  // Two requests on one kept-alive connection: Nagle's delay hit the second.
  for (int i = 0; i < 2; ++i) {
    const auto start = std::chrono::steady_clock::now();
    httplib::Result result = client.Get("/nodelay");
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(result);
    EXPECT_EQ(result->body, "1") << "TCP_NODELAY on request " << i;
    std::printf("keep-alive request %d: %.3f ms\n", i, ms);
  }
}

TEST_F(GuardedServerTest, MethodsTheServerDoesNotRouteGet501AndTheConnectionCloses) {
  for (const char* method : {"PRI", "TRACE", "CONNECT", "FOO"}) {
    bool closed = false;
    // A body follows; it must not be read, and the connection must not be kept.
    const std::string answer =
        Exchange(std::string(method) + " /hello HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhelloGET /hello HTTP/1.1\r\n\r\n",
                 &closed);
    EXPECT_EQ(StatusLine(answer), "HTTP/1.1 501 Not Implemented") << method << ": " << answer;
    EXPECT_EQ(answer.find("HTTP/1.1 200"), std::string::npos) << method << ": the body was read as a request";
    EXPECT_TRUE(closed) << method;
  }
}

TEST_F(GuardedServerTest, ABodyOverTheLimitIsRefusedBeforeItIsSent) {
  for (const char* method : {"POST", "PUT", "PATCH", "DELETE", "GET", "OPTIONS"}) {
    Socket socket(port_);
    ASSERT_TRUE(socket.connected());
    // Only the head: the answer comes without a byte of the body.
    ASSERT_TRUE(socket.Send(std::string(method) + " /echo HTTP/1.1\r\nHost: x\r\nContent-Length: " +
                            std::to_string(kBodyLimit + 1) + "\r\n\r\n"));
    EXPECT_EQ(StatusLine(socket.ReadResponse()), "HTTP/1.1 413 Payload Too Large") << method;
    // Then the connection is closed: a large body is not read whole.
    EXPECT_LT(socket.SendUpTo(uint64_t{256} << 20, 'x'), uint64_t{256} << 20) << method;
  }
  Socket expecting(port_);
  ASSERT_TRUE(expecting.Send("POST /echo HTTP/1.1\r\nHost: x\r\nExpect: 100-continue\r\nContent-Length: " +
                             std::to_string(kBodyLimit + 1) + "\r\n\r\n"));
  EXPECT_EQ(StatusLine(expecting.ReadResponse()), "HTTP/1.1 413 Payload Too Large");
}

TEST_F(GuardedServerTest, ABodyWithinTheLimitIsRead) {
  const std::string answer = Exchange("POST /echo HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\nConnection: close\r\n\r\nhello");
  EXPECT_EQ(StatusLine(answer), "HTTP/1.1 200 OK") << answer;
  EXPECT_EQ(answer.substr(answer.size() - 5), "hello");
}

TEST_F(GuardedServerTest, UnclearFramingIsRefused) {
  EXPECT_EQ(StatusLine(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\n")),
            "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(StatusLine(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 5\r\nContent-Length: 5\r\n\r\nhello")),
            "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(StatusLine(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 0x5\r\n\r\nhello")),
            "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(StatusLine(Exchange("POST /echo HTTP/1.1\r\nTransfer-Encoding: gzip\r\n\r\nhello")),
            "HTTP/1.1 501 Not Implemented");
}

TEST_F(GuardedServerTest, ABodyTheLibraryLeavesUnreadClosesTheConnectionAfterTheAnswer) {
  bool closed = false;
  // httplib never reads a GET's body: its bytes, a request here, must not be served.
  const std::string answer =
      Exchange("GET /hello HTTP/1.1\r\nContent-Length: 27\r\n\r\nGET /nodelay HTTP/1.1\r\n\r\n", &closed);
  EXPECT_EQ(StatusLine(answer), "HTTP/1.1 200 OK") << answer;
  EXPECT_EQ(answer.find("HTTP/1.1", 1), std::string::npos) << answer;
  EXPECT_TRUE(closed);
}

TEST_F(GuardedServerTest, AnEndlessRequestLineOrHeaderIsCutOff) {
  for (const std::string& head : {std::string(), std::string("GET /hello HTTP/1.1\r\nX-Long: ")}) {
    Socket socket(port_);
    ASSERT_TRUE(socket.connected());
    ASSERT_TRUE(socket.Send(head));
    EXPECT_LT(socket.SendUpTo(uint64_t{256} << 20, 'a'), uint64_t{256} << 20) << head;
  }
  // Headers without end, each line short.
  Socket many(port_);
  ASSERT_TRUE(many.Send("GET /hello HTTP/1.1\r\n"));
  std::string lines;
  for (int i = 0; i < 4096; ++i) lines += "X-" + std::to_string(i) + ": y\r\n";
  uint64_t sent = 0;
  while (sent < (uint64_t{256} << 20) && many.Send(lines)) sent += lines.size();
  EXPECT_LT(sent, uint64_t{256} << 20);
  // The server goes on.
  httplib::Client client("127.0.0.1", port_);
  EXPECT_EQ(client.Get("/hello")->body, "hello");
}

TEST_F(GuardedServerTest, KeepAliveRequestsGoOnOneConnection) {
  Socket socket(port_);
  ASSERT_TRUE(socket.connected());
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(socket.Send("GET /hello HTTP/1.1\r\nHost: x\r\n\r\n"));
    EXPECT_EQ(StatusLine(socket.ReadResponse()), "HTTP/1.1 200 OK") << i;
  }
}

TEST(GuardedServerBodyLimitTest, WithoutALimitNoBodyIsTaken) {
  auto server = std::make_unique<GuardedServer>();
  server->Post("/echo", [](const httplib::Request&, httplib::Response& response) { response.status = 204; });
  HttpListener listener;
  const int port = listener.Start(std::move(server), "127.0.0.1", 0);
  httplib::Client client("127.0.0.1", port);
  EXPECT_EQ(client.Post("/echo", "x", "text/plain")->status, 413);
  EXPECT_EQ(client.Post("/echo")->status, 204);
  Socket chunked(port);
  ASSERT_TRUE(chunked.Send("POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n1\r\nx\r\n0\r\n\r\n"));
  EXPECT_EQ(StatusLine(chunked.ReadToEnd()), "HTTP/1.1 413 Payload Too Large");
}

TEST(HttpListenerTest, ServesOnlyAGuardedServer) {
  HttpListener listener;
  EXPECT_THROW(listener.Start(std::make_unique<httplib::Server>(), "127.0.0.1", 0), std::logic_error);
}

TEST(RawHeaderValuesTest, ValuesAreTheBytesSent) {
  const std::string head = std::string("GET /x HTTP/1.1\r\n") +
                           "authorization:   Bearer TOK%45N \t\r\n"
                           "X-Nul: a" + std::string(1, '\0') + "b\r\n"
                           "X-Bare-Lf: skipped\n"
                           "Authorization : not this one\r\n"
                           "X-Empty:\r\n"
                           "\r\n"
                           "Authorization: after the head\r\n";
  EXPECT_EQ(RawHeaderValues(head, "Authorization"), std::vector<std::string>{"Bearer TOK%45N"});
  EXPECT_EQ(RawHeaderValues(head, "x-nul"), std::vector<std::string>{std::string("a\0b", 3)});
  EXPECT_TRUE(RawHeaderValues(head, "X-Bare-Lf").empty());
  EXPECT_TRUE(RawHeaderValues(head, "X-Empty").empty());
  EXPECT_EQ(RawHeaderValues("GET / HTTP/1.1\r\nA: 1\r\nA: 2\r\n\r\n", "a"), (std::vector<std::string>{"1", "2"}));
}

}  // namespace
}  // namespace tcfarm
