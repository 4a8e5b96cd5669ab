// Deadlines, idle limits and keepalive against a real server process that stops answering
// without closing anything (SIGSTOP: its kernel still holds the connection, as a hung or
// frozen server does): every client call ends within the limit it was given.
#include <gtest/gtest.h>
#include <signal.h>

#include <atomic>
#include <fstream>
#include <map>
#include <thread>

#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

class DeadlinesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerChild>(
        std::vector<std::string>{"--log-level", "warn", "--threads", "1", "--backends",
                                 "sse,passthrough", "--default-backend", "sse"});
    ASSERT_TRUE(server_->ready()) << server_->error();
  }
  void TearDown() override {
    if (server_ && server_->pid() > 0) kill(server_->pid(), SIGCONT);
  }
  // SIGSTOP is delivered asynchronously: wait until the kernel says the process stopped
  // (state 'T' in /proc/PID/stat), so nothing it answers afterwards is a race.
  void Freeze() {
    ASSERT_EQ(kill(server_->pid(), SIGSTOP), 0);
    const std::string stat = "/proc/" + std::to_string(server_->pid()) + "/stat";
    for (int i = 0; i < 1000; ++i) {
      std::ifstream in(stat);
      std::string line;
      std::getline(in, line);
      const std::size_t close = line.rfind(')');
      if (close != std::string::npos && close + 2 < line.size() && line[close + 2] == 'T') return;
      std::this_thread::sleep_for(1ms);
    }
    FAIL() << "the server did not stop within 1 s of SIGSTOP";
  }

  // Streams frames until the stream ends; the server is frozen once `answered_before`
  // frames came back. Returns the stream's status; `frozen` and `ended` when that happened.
  Status StreamUntilFrozen(client::SkinClient& client, uint64_t answered_before,
                           Clock::time_point* frozen, client::StreamSummary* summary,
                           std::map<std::string, int>* failures) {
    auto info = client.Upload(MakeSyntheticMesh({.vertex_count = 2000, .joint_count = 12}));
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    if (!info.ok()) return info.status();
    std::atomic<uint64_t> answered{0};
    std::atomic<bool> froze{false};
    return client::StreamFrames(
        client,
        {.mesh_id = info->mesh_id(),
         .backend = "sse",
         .frames = UINT64_MAX / 2,
         .window = 4,
         .max_reconnects = 0},
        [&](uint64_t f) {
          if (answered.load() >= answered_before && !froze.exchange(true)) {
            Freeze();
            *frozen = Clock::now();
          }
          return MakeSyntheticPalette(12, 1, f);
        },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          if (r.status.ok()) {
            answered.fetch_add(1);
          } else {
            ++(*failures)[StatusCodeName(r.status.code())];
          }
        },
        summary);
  }

  std::unique_ptr<ServerChild> server_;
};

TEST_F(DeadlinesTest, AUnaryCallEndsAtItsDeadline) {
  client::SkinClient client(client::MakeChannel(server_->target()), {.deadline = 500ms});
  ASSERT_TRUE(client.GetServerStats().ok());
  Freeze();
  const auto started = Clock::now();
  const Status s = client.GetServerStats().status();
  const double took = SecondsSince(started);
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded) << s.ToString();
  EXPECT_GE(took, 0.45);
  EXPECT_LT(took, 2.0);
  client::FrameResult result;
  const auto skin_started = Clock::now();
  const Status skin = client.Skin("0123", "sse", MakeSyntheticPalette(12, 1, 0), 0, false, &result);
  EXPECT_EQ(skin.code(), StatusCode::kDeadlineExceeded) << skin.ToString();
  EXPECT_LT(SecondsSince(skin_started), 2.0);
}

// Keepalive off: the stream's idle limit alone ends it.
TEST_F(DeadlinesTest, AStreamEndsAtItsIdleLimit) {
  client::ChannelOptions no_keepalive;
  no_keepalive.keepalive_time = 0ms;
  client::SkinClient client(client::MakeChannel(server_->target(), no_keepalive),
                            {.stream_idle = 1000ms});
  Clock::time_point frozen;
  client::StreamSummary summary;
  std::map<std::string, int> failures;
  const Status s = StreamUntilFrozen(client, 20, &frozen, &summary, &failures);
  const double took = SecondsSince(frozen);
  EXPECT_EQ(s.code(), StatusCode::kDeadlineExceeded) << s.ToString();
  EXPECT_GE(took, 0.9);
  EXPECT_LT(took, 3.0) << s.ToString();
  EXPECT_EQ(summary.sent, summary.answered + summary.failed);
  EXPECT_GT(summary.failed, 0u);
  EXPECT_EQ(failures["DEADLINE_EXCEEDED"], static_cast<int>(summary.failed));
  std::cout << "idle limit 1 s: the stream ended " << took
            << " s after the server froze: " << s.ToString() << "\n";
}

// The idle limit off: keepalive (a ping every 2 s, 1 s to answer) ends it.
TEST_F(DeadlinesTest, KeepaliveGivesUpOnAServerThatStopsAnswering) {
  client::ChannelOptions keepalive;
  keepalive.keepalive_time = 2000ms;
  keepalive.keepalive_timeout = 1000ms;
  client::SkinClient client(client::MakeChannel(server_->target(), keepalive),
                            {.stream_idle = 0ms});
  Clock::time_point frozen;
  client::StreamSummary summary;
  std::map<std::string, int> failures;
  const Status s = StreamUntilFrozen(client, 20, &frozen, &summary, &failures);
  const double took = SecondsSince(frozen);
  EXPECT_EQ(s.code(), StatusCode::kUnavailable) << s.ToString();
  EXPECT_LT(took, 2.0 + 1.0 + 1.0) << s.ToString();  // time + timeout + a second's slack
  EXPECT_EQ(summary.sent, summary.answered + summary.failed);
  EXPECT_EQ(failures["UNAVAILABLE"], static_cast<int>(summary.failed));
  std::cout << "keepalive 2 s + 1 s: the stream ended " << took
            << " s after the server froze: " << s.ToString() << "\n";
}

}  // namespace
}  // namespace skinserve::testing
