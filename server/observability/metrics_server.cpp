#include "observability/metrics_server.h"

#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>
#include <vector>

#include "observability/metrics_listen_socket.h"
#include "observability/metrics_request.h"

namespace skinserve::server {

namespace {

using Clock = std::chrono::steady_clock;
namespace limits = metrics_port;

// One accepted connection, through its three phases: reading the request head (at most
// kMaxRequestHeadBytes, until kRequestTimeout), writing the answer (until kAnswerTimeout),
// then reading and dropping what the client still sends (kMaxDiscardBytes, kLinger).
struct Connection {
  enum class Phase { kReading, kWriting, kDiscarding };
  int fd = -1;
  Phase phase = Phase::kReading;
  Clock::time_point deadline;
  std::string head;  // what arrived of the request head
  std::size_t head_used = 0;
  std::string answer;
  std::size_t written = 0;
  std::size_t discarded = 0;
};

bool WouldBlock(int error) { return error == EAGAIN || error == EWOULDBLOCK || error == EINTR; }

}  // namespace

// The poll() loop of the metrics thread. Every connection's memory is its head buffer and
// its answer, and there are at most kMaxConnections of them.
class MetricsServer::Loop {
 public:
  Loop(int listen_fd, Render render)
      : listen_fd_(listen_fd),
        wake_fd_(eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)),
        render_(std::move(render)) {
    connections_.reserve(limits::kMaxConnections);
  }
  ~Loop() {
    for (Connection& c : connections_) Close(c);
    if (listen_fd_ >= 0) close(listen_fd_);
    if (wake_fd_ >= 0) close(wake_fd_);
  }
  bool ok() const { return wake_fd_ >= 0; }

  void Run();
  void RequestStop() {
    stop_requested_.store(true);
    const uint64_t one = 1;
    if (write(wake_fd_, &one, sizeof(one)) < 0) {  // cannot happen: the counter cannot overflow
      spdlog::error("metrics port: cannot wake its thread to stop: {}", std::strerror(errno));
    }
  }

 private:
  void BeginStop();
  void AcceptAll();
  void Step(Connection& c, short revents);
  void Read(Connection& c);
  void Write(Connection& c);
  void Discard(Connection& c);
  void Expire(Connection& c, Clock::time_point now);
  void Answer(Connection& c, std::string answer);
  void Close(Connection& c) {
    if (c.fd >= 0) close(c.fd);
    c.fd = -1;
  }
  void NoteRefused(const char* why);
  int PollTimeoutMs(Clock::time_point now) const;

  int listen_fd_;
  int wake_fd_;
  Render render_;
  std::vector<Connection> connections_;
  std::atomic<bool> stop_requested_{false};
  bool stopping_ = false;
  Clock::time_point accept_paused_until_{};
  // Refused connections are logged once a minute at most, not once each (a flood).
  uint64_t refused_ = 0;
  Clock::time_point last_refusal_log_{};
};

void MetricsServer::Loop::Run() {
  // Lower priority than gRPC's and the compute threads: a flood of this port yields the cores.
  if (setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), limits::kThreadNice) != 0) {
    spdlog::warn("metrics port: cannot lower its thread's priority: {}", std::strerror(errno));
  }
  std::vector<pollfd> polled;
  for (;;) {
    const Clock::time_point now = Clock::now();
    for (Connection& c : connections_) Expire(c, now);
    std::erase_if(connections_, [](const Connection& c) { return c.fd < 0; });
    // Checked after the expiries: a stop waits for the last answer, not for a wake-up that
    // will never come once that answer's connection is gone.
    if (stopping_ && connections_.empty()) return;
    polled.clear();
    polled.push_back({wake_fd_, POLLIN, 0});
    const bool accepting = !stopping_ && now >= accept_paused_until_;
    polled.push_back({accepting ? listen_fd_ : -1, POLLIN, 0});
    for (const Connection& c : connections_) {
      polled.push_back(
          {c.fd, static_cast<short>(c.phase == Connection::Phase::kWriting ? POLLOUT : POLLIN), 0});
    }
    if (poll(polled.data(), polled.size(), PollTimeoutMs(now)) < 0 && errno != EINTR) {
      spdlog::error("metrics port: poll failed, no more scrapes: {}", std::strerror(errno));
      return;
    }
    if (polled[0].revents != 0 || (stop_requested_.load() && !stopping_)) BeginStop();
    for (std::size_t i = 0; i < connections_.size(); ++i) {
      Connection& c = connections_[i];  // closed by BeginStop: fd -1
      if (c.fd >= 0 && polled[i + 2].revents != 0) Step(c, polled[i + 2].revents);
    }
    std::erase_if(connections_, [](const Connection& c) { return c.fd < 0; });
    if (polled[1].revents != 0 && !stopping_) AcceptAll();
  }
}

// No new connections; those still sending their request are closed, answers being written
// (and their lingers) finish within their deadlines.
void MetricsServer::Loop::BeginStop() {
  uint64_t count = 0;
  (void)!read(wake_fd_, &count, sizeof(count));
  stopping_ = true;
  if (listen_fd_ >= 0) close(listen_fd_);
  listen_fd_ = -1;
  for (Connection& c : connections_) {
    if (c.phase == Connection::Phase::kReading) Close(c);
  }
}

void MetricsServer::Loop::AcceptAll() {
  // Bounded per wake-up, so a connect flood cannot starve the connections being served.
  for (std::size_t i = 0; i < 4 * limits::kMaxConnections; ++i) {
    const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == ECONNABORTED || errno == EINTR) continue;
      if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
        // The connection stays in the backlog; retrying at once would spin.
        accept_paused_until_ = Clock::now() + std::chrono::milliseconds(100);
        NoteRefused(std::strerror(errno));
      }
      return;
    }
    if (connections_.size() >= limits::kMaxConnections) {
      close(fd);
      NoteRefused("connections over the cap");
      continue;
    }
    Connection& c = connections_.emplace_back();
    c.fd = fd;
    c.deadline = Clock::now() + limits::kRequestTimeout;
  }
}

void MetricsServer::Loop::NoteRefused(const char* why) {
  ++refused_;
  const Clock::time_point now = Clock::now();
  if (now - last_refusal_log_ < std::chrono::minutes(1)) return;
  spdlog::warn(
      "metrics port: {} connection(s) closed at accept ({}; at most {} are served at once)",
      refused_, why, limits::kMaxConnections);
  refused_ = 0;
  last_refusal_log_ = now;
}

int MetricsServer::Loop::PollTimeoutMs(Clock::time_point now) const {
  Clock::time_point next = Clock::time_point::max();
  for (const Connection& c : connections_) next = std::min(next, c.deadline);
  if (accept_paused_until_ > now) next = std::min(next, accept_paused_until_);
  if (next == Clock::time_point::max()) return -1;
  const auto wait = std::chrono::ceil<std::chrono::milliseconds>(next - now).count();
  return static_cast<int>(std::clamp<int64_t>(wait, 0, 60'000));
}

void MetricsServer::Loop::Expire(Connection& c, Clock::time_point now) {
  if (now < c.deadline) return;
  if (c.phase == Connection::Phase::kReading) {
    Answer(c, RefusalAnswer(MetricsRefusal::kTimeout));  // a slow sender
  } else {
    Close(c);  // a client that does not read its answer, or the linger is over
  }
}

void MetricsServer::Loop::Step(Connection& c, short revents) {
  switch (c.phase) {
    case Connection::Phase::kReading:
      if (revents & (POLLIN | POLLHUP | POLLERR)) Read(c);
      break;
    case Connection::Phase::kWriting:
      if (revents & (POLLOUT | POLLHUP | POLLERR)) Write(c);
      break;
    case Connection::Phase::kDiscarding:
      if (revents & (POLLIN | POLLHUP | POLLERR)) Discard(c);
      break;
  }
}

void MetricsServer::Loop::Read(Connection& c) {
  if (c.head.empty()) c.head.resize(limits::kMaxRequestHeadBytes);  // the only head buffer
  const std::size_t before = c.head_used;
  const ssize_t n = recv(c.fd, c.head.data() + before, c.head.size() - before, 0);
  if (n == 0 || (n < 0 && !WouldBlock(errno))) return Close(c);  // the client went away
  if (n < 0) return;
  c.head_used += static_cast<std::size_t>(n);
  const std::string_view received(c.head.data(), c.head_used);
  const std::size_t end = RequestHeadEnd(received, before);
  if (end == std::string_view::npos) {
    if (c.head_used == c.head.size()) Answer(c, RefusalAnswer(MetricsRefusal::kHeadTooLong));
    return;
  }
  const MetricsRequest request = JudgeRequestHead(received.substr(0, end));
  switch (request) {
    case MetricsRequest::kScrape:
    case MetricsRequest::kScrapeHead:
      try {
        return Answer(c, ScrapeAnswer(render_(), request == MetricsRequest::kScrape));
      } catch (const std::exception& e) {
        spdlog::error("metrics port: rendering the metrics failed: {}", e.what());
        return Answer(c, RefusalAnswer(MetricsRefusal::kRenderFailed));
      }
    case MetricsRequest::kBadRequest:
      return Answer(c, RefusalAnswer(MetricsRefusal::kBadRequest));
    case MetricsRequest::kNotFound:
      return Answer(c, RefusalAnswer(MetricsRefusal::kNotFound));
    case MetricsRequest::kMethodNotAllowed:
      return Answer(c, RefusalAnswer(MetricsRefusal::kMethodNotAllowed));
  }
}

void MetricsServer::Loop::Answer(Connection& c, std::string answer) {
  std::string().swap(c.head);  // the head is judged: its buffer goes back now
  c.head_used = 0;
  c.answer = std::move(answer);
  c.phase = Connection::Phase::kWriting;
  c.deadline = Clock::now() + limits::kAnswerTimeout;
  Write(c);
}

void MetricsServer::Loop::Write(Connection& c) {
  while (c.written < c.answer.size()) {
    const ssize_t n = send(c.fd, c.answer.data() + c.written, c.answer.size() - c.written,
                           MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0 && WouldBlock(errno)) return;  // poll for POLLOUT
    if (n <= 0) return Close(c);             // the client went away
    c.written += static_cast<std::size_t>(n);
  }
  std::string().swap(c.answer);
  // FIN after the answer; the connection stays open for the linger, so that closing it with
  // a body still arriving does not reset it before the client has read the answer.
  shutdown(c.fd, SHUT_WR);
  c.phase = Connection::Phase::kDiscarding;
  c.deadline = Clock::now() + limits::kLinger;
}

void MetricsServer::Loop::Discard(Connection& c) {
  char scratch[4096];
  const ssize_t n = recv(c.fd, scratch, sizeof(scratch), 0);
  if (n < 0 && WouldBlock(errno)) return;
  if (n <= 0) return Close(c);  // the client closed too: done
  c.discarded += static_cast<std::size_t>(n);
  if (c.discarded > limits::kMaxDiscardBytes) Close(c);
}

Result<std::unique_ptr<MetricsServer>> MetricsServer::Start(const std::string& listen,
                                                            Render render) {
  auto socket = OpenListenSocket(listen);
  if (!socket.ok()) return socket.status();
  std::unique_ptr<MetricsServer> server(new MetricsServer());
  server->port_ = socket->port;
  server->loop_ = std::make_unique<Loop>(socket->fd, std::move(render));
  if (!server->loop_->ok()) {
    return Unavailable(std::string("--metrics-listen: cannot create the metrics thread's "
                                   "wake-up descriptor (eventfd): ") +
                       std::strerror(errno));
  }
  Loop* loop = server->loop_.get();
  server->thread_ = std::thread([loop] { loop->Run(); });
  return server;
}

MetricsServer::~MetricsServer() { Stop(); }

void MetricsServer::Stop() {
  if (!thread_.joinable()) return;
  loop_->RequestStop();
  thread_.join();
}

}  // namespace skinserve::server
