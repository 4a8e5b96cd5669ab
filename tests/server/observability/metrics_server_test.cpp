// The metrics port's HTTP rules (issue 42), on a real MetricsServer over loopback: GET and
// HEAD of /metrics are answered, every other request is refused with a status that says
// why and the connection closed; a request head is bounded at kMaxRequestHeadBytes; a
// taken port (SO_REUSEPORT or not) fails Start, naming it; Stop closes connections still
// sending. The flood itself, against a whole server process: tests/stress.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <future>
#include <memory>
#include <string>
#include <thread>

#include "observability/metrics_server.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;
using server::MetricsServer;
namespace limits = server::metrics_port;

const std::string kExposition =
    "# TYPE skinserve_compute_threads gauge\nskinserve_compute_threads 3\n";

int Connect(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);
  return fd;
}

// Everything the server sends until it closes the connection (10 s at most: "did not hang").
std::string ReadAll(int fd) {
  std::string out;
  char buffer[4096];
  for (const auto end = std::chrono::steady_clock::now() + 10s;
       std::chrono::steady_clock::now() < end;) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 100) <= 0) continue;
    const ssize_t n = recv(fd, buffer, sizeof(buffer), 0);
    if (n <= 0) return out;
    out.append(buffer, static_cast<std::size_t>(n));
  }
  ADD_FAILURE() << "the server did not close the connection within 10 s";
  return out;
}

// Sends `request` on a new connection and returns the whole answer.
std::string Ask(int port, const std::string& request) {
  const int fd = Connect(port);
  EXPECT_EQ(send(fd, request.data(), request.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(request.size()));
  std::string answer = ReadAll(fd);
  close(fd);
  return answer;
}

class MetricsPortTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto started = MetricsServer::Start("127.0.0.1:0", [] { return kExposition; });
    ASSERT_TRUE(started.ok()) << started.status().ToString();
    server_ = std::move(started).value();
    port_ = server_->port();
  }
  std::unique_ptr<MetricsServer> server_;
  int port_ = 0;
};

TEST_F(MetricsPortTest, GetAndHeadOfMetricsAreAnswered) {
  const std::string got = Ask(port_, "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_TRUE(got.starts_with("HTTP/1.1 200 OK\r\n")) << got;
  EXPECT_NE(got.find("\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\n"),
            std::string::npos)
      << got;
  EXPECT_NE(got.find("\r\nContent-Length: " + std::to_string(kExposition.size()) + "\r\n"),
            std::string::npos)
      << got;
  EXPECT_NE(got.find("\r\nConnection: close\r\n"), std::string::npos) << got;
  EXPECT_TRUE(got.ends_with("\r\n\r\n" + kExposition)) << got;
  // HTTP/1.0, a query string, lenient line ends: the same scrape.
  EXPECT_TRUE(Ask(port_, "GET /metrics?x=1 HTTP/1.0\n\n").ends_with("\r\n\r\n" + kExposition));
  const std::string head = Ask(port_, "HEAD /metrics HTTP/1.1\r\n\r\n");
  EXPECT_TRUE(head.starts_with("HTTP/1.1 200 OK\r\n")) << head;
  EXPECT_NE(head.find("\r\nContent-Length: " + std::to_string(kExposition.size()) + "\r\n"),
            std::string::npos);
  EXPECT_TRUE(head.ends_with("\r\n\r\n")) << "HEAD got a body: " << head;
}

TEST_F(MetricsPortTest, EveryOtherRequestIsRefusedWithItsReason) {
  const std::string post = Ask(port_, "POST /metrics HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello");
  EXPECT_TRUE(post.starts_with("HTTP/1.1 405 Method Not Allowed\r\n")) << post;
  EXPECT_NE(post.find("\r\nAllow: GET, HEAD\r\n"), std::string::npos) << post;
  EXPECT_TRUE(Ask(port_, "PUT /metrics HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 405 "));
  EXPECT_TRUE(Ask(port_, "DELETE / HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 405 "));
  const std::string other = Ask(port_, "GET /debug HTTP/1.1\r\n\r\n");
  EXPECT_TRUE(other.starts_with("HTTP/1.1 404 Not Found\r\n")) << other;
  EXPECT_NE(other.find("GET /metrics only"), std::string::npos) << other;
  EXPECT_TRUE(Ask(port_, "GET /metricsX HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 404 "));
  EXPECT_TRUE(Ask(port_, "GET /metrics HTTP/2.0\r\n\r\n").starts_with("HTTP/1.1 400 "));
  EXPECT_TRUE(Ask(port_, "hello\r\n\r\n").starts_with("HTTP/1.1 400 "));
  EXPECT_TRUE(Ask(port_, "GET  /metrics HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 400 "));
}

TEST_F(MetricsPortTest, RequestHeadIsBoundedWhereStated) {
  const std::string line = "GET /metrics HTTP/1.1\r\nX-Fill: ";
  const std::string end = "\r\n\r\n";
  // A head of exactly the bound is a scrape; one byte more is refused, read no further.
  const std::string at_bound(limits::kMaxRequestHeadBytes - line.size() - end.size(), 'a');
  EXPECT_TRUE(Ask(port_, line + at_bound + end).starts_with("HTTP/1.1 200 OK\r\n"));
  const std::string over = Ask(port_, line + at_bound + "a" + end);
  EXPECT_TRUE(over.starts_with("HTTP/1.1 431 ")) << over;
  EXPECT_NE(over.find(std::to_string(limits::kMaxRequestHeadBytes) + " bytes"), std::string::npos)
      << over;
  // A request line alone over the bound, never ended.
  EXPECT_TRUE(Ask(port_, "GET /" + std::string(limits::kMaxRequestHeadBytes, 'm'))
                  .starts_with("HTTP/1.1 431 "));
}

TEST_F(MetricsPortTest, ATakenPortFailsStartNamingIt) {
  // Held with SO_REUSEPORT as well: a server that set it too would share the port.
  const int holder = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const int yes = 1;
  setsockopt(holder, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  setsockopt(holder, SOL_SOCKET, SO_REUSEPORT, &yes, sizeof(yes));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(holder, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);
  ASSERT_EQ(listen(holder, 1), 0);
  socklen_t length = sizeof(address);
  getsockname(holder, reinterpret_cast<sockaddr*>(&address), &length);
  const int port = ntohs(address.sin_port);
  auto second = MetricsServer::Start("127.0.0.1:" + std::to_string(port), [] { return ""; });
  close(holder);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.status().message().find("port " + std::to_string(port)), std::string::npos)
      << second.status().ToString();
  EXPECT_NE(second.status().message().find("--metrics-listen"), std::string::npos);
  auto bad = MetricsServer::Start("127.0.0.1:99999", [] { return ""; });
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("0..65535"), std::string::npos);
}

// Stops the fixture's server on a thread of its own; false if Stop has not returned within
// `bound` ("did not hang"; the thread and the server are then left behind, so that the
// other tests still run).
bool StopWithin(std::unique_ptr<MetricsServer> server, std::chrono::seconds bound) {
  auto stopped = std::make_shared<std::promise<void>>();
  std::future<void> done = stopped->get_future();
  std::thread([server = server.release(), stopped] {
    server->Stop();
    stopped->set_value();
    delete server;
  }).detach();
  return done.wait_for(bound) == std::future_status::ready;
}

TEST_F(MetricsPortTest, StopClosesConnectionsStillSendingTheirRequest) {
  const int fd = Connect(port_);
  ASSERT_EQ(send(fd, "GET /met", 8, MSG_NOSIGNAL), 8);
  // The request is on its way in; Stop must not wait for the rest (or the timeout's 408).
  std::this_thread::sleep_for(100ms);
  ASSERT_TRUE(StopWithin(std::move(server_), 20s)) << "Stop hangs";
  EXPECT_EQ(ReadAll(fd), "") << "a connection still sending was answered, not closed";
  close(fd);
}

TEST_F(MetricsPortTest, StopReturnsOnceTheLastAnswerIsOut) {
  // Answered, and held open by the client: the server lingers (reading what else comes)
  // until kLinger; Stop returns once that connection is gone.
  const int fd = Connect(port_);
  const std::string request = "GET /metrics HTTP/1.1\r\n\r\n";
  ASSERT_EQ(send(fd, request.data(), request.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(request.size()));
  EXPECT_TRUE(ReadAll(fd).ends_with(kExposition));
  ASSERT_TRUE(StopWithin(std::move(server_), 20s))
      << "Stop hangs once the last connection has expired";
  close(fd);
}

}  // namespace
}  // namespace skinserve::testing
