// The real `skinserve` binary as a child process: --help, and SIGTERM while streams are
// in flight (every frame answered or reported failed, none lost; exit status 0).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <thread>

#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/core/synthetic.h"

namespace skinserve::testing {
namespace {

std::string RunAndCapture(const std::string& command) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buffer[4096];
  while (std::size_t n = fread(buffer, 1, sizeof(buffer), pipe)) out.append(buffer, n);
  pclose(pipe);
  return out;
}

int FreePort() {
  // Port 0 is not an option for a child we then connect to: ask for a free one.
  static int next = 42000 + static_cast<int>(getpid() % 2000) * 5;
  return next++;
}

TEST(ServerProcessTest, HelpDocumentsEveryOption) {
  const std::string help = RunAndCapture(std::string(SKINSERVE_SERVER_BINARY) + " --help");
  for (const char* option :
       {"--listen", "--threads", "--backends", "--default-backend", "--mesh-budget-mb",
        "--max-vertices", "--max-joints", "--queue", "--stream-window", "--log-level",
        "--drain-seconds", "SKINSERVE_LISTEN", "SKINSERVE_THREADS"}) {
    EXPECT_NE(help.find(option), std::string::npos) << option << " missing from --help";
  }
}

TEST(ServerProcessTest, SigtermDrainsStreamsInFlightAndExitsZero) {
  const std::string listen = "127.0.0.1:" + std::to_string(FreePort());
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    execl(SKINSERVE_SERVER_BINARY, SKINSERVE_SERVER_BINARY, "--listen", listen.c_str(),
          "--log-level", "warn", "--drain-seconds", "5", static_cast<char*>(nullptr));
    _exit(127);
  }
  auto channel = client::MakeChannel(listen);
  ASSERT_TRUE(client::WaitUntilServing(*channel, std::chrono::seconds(30)).ok());
  client::SkinClient setup(channel);
  auto info = setup.Upload(MakeSyntheticMesh({.vertex_count = 100'000, .influences = 2}));
  ASSERT_TRUE(info.ok());

  std::atomic<uint64_t> sent{0}, answered{0}, failed{0}, sink_calls{0};
  std::vector<std::thread> streams;
  for (int s = 0; s < 4; ++s) {
    streams.emplace_back([&, s] {
      client::SkinClient own(client::MakeChannel(listen));
      client::StreamSummary summary;
      // The stream ends UNAVAILABLE or CANCELLED when the server stops: expected here.
      (void)client::StreamFrames(
          own,
          {.mesh_id = info->mesh_id(),
           .backend = s % 2 ? "serial" : "sse",
           .frames = 100000,
           .window = 4,
           .max_reconnects = 0},
          [](uint64_t f) { return MakeSyntheticPalette(77, 1, f); },
          [&](client::FrameResult&, std::chrono::nanoseconds) { sink_calls.fetch_add(1); },
          &summary);
      sent += summary.sent;
      answered += summary.answered;
      failed += summary.failed;
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  ASSERT_EQ(kill(child, SIGTERM), 0);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  for (auto& thread : streams) thread.join();
  EXPECT_TRUE(WIFEXITED(status)) << "killed by a signal instead of exiting";
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_GT(answered.load(), 0u);
  EXPECT_EQ(sent.load(), answered.load() + failed.load()) << "a frame was lost silently";
  EXPECT_EQ(sink_calls.load(), sent.load());
}

}  // namespace
}  // namespace skinserve::testing
