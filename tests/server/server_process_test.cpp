// The real `skinserve` binary as a child process: --help, and SIGTERM while streams are
// in flight (every frame answered or reported failed, none lost; exit status 0).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <thread>

#include "process_probe.h"
#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

TEST(ServerProcessTest, HelpDocumentsEveryOption) {
  const std::string help = RunAndCapture(std::string(SKINSERVE_SERVER_BINARY) + " --help");
  for (const char* option :
       {"--listen", "--threads", "--backends", "--default-backend", "--mesh-budget-mb",
        "--max-vertices", "--max-joints", "--queue", "--stream-window", "--log-level",
        "--drain-seconds", "--port-file", "SKINSERVE_LISTEN", "SKINSERVE_THREADS"}) {
    EXPECT_NE(help.find(option), std::string::npos) << option << " missing from --help";
  }
}

TEST(ServerProcessTest, UnwritablePortFileIsAStartUpErrorNamingTheOption) {
  const std::string out = RunAndCapture(std::string(SKINSERVE_SERVER_BINARY) +
                                        " --listen 127.0.0.1:0 --log-level warn --port-file "
                                        "/nonexistent-skinserve-dir/port 2>&1; echo exit=$?");
  EXPECT_NE(out.find("--port-file: cannot write /nonexistent-skinserve-dir/port"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("exit=1"), std::string::npos) << out;
}

// Budgets that could together make the server hold more than its memory: it does not
// start (an OOM kill later would take every client's streams), and says which budgets.
TEST(ServerProcessTest, BudgetsOverTheMemoryEnvelopeAreAStartUpErrorNamingThem) {
  const std::string server = std::string(SKINSERVE_SERVER_BINARY) +
                             " --listen 127.0.0.1:0 --log-level warn --memory-limit-mb 3072 ";
  const std::string out = RunAndCapture(server + "--mesh-budget-mb 1024 2>&1; echo exit=$?");
  EXPECT_NE(out.find("the budgets do not fit the memory"), std::string::npos) << out;
  EXPECT_NE(out.find("--mesh-budget-mb 1024 MiB x 2.5"), std::string::npos) << out;
  EXPECT_NE(out.find("exit=1"), std::string::npos) << out;
  // --memory-envelope prints the same sum and says whether it fits.
  const std::string fits =
      RunAndCapture(server + "--mesh-budget-mb 512 --memory-envelope 2>&1; echo exit=$?");
  EXPECT_NE(fits.find("--mesh-budget-mb 512 MiB x 2.5"), std::string::npos) << fits;
  EXPECT_NE(fits.find("--inflight-budget-mb"), std::string::npos) << fits;
  EXPECT_NE(fits.find("\nfits\nexit=0"), std::string::npos) << fits;
}

TEST(ServerProcessTest, SigtermDrainsStreamsInFlightAndExitsZero) {
  ServerChild server({"--log-level", "warn", "--drain-seconds", "5"});
  ASSERT_TRUE(server.ready()) << server.error();
  const std::string listen = server.target();
  auto channel = client::MakeChannel(listen);
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
  const int status = server.Stop(SIGTERM);
  ASSERT_NE(status, -1);
  for (auto& thread : streams) thread.join();
  EXPECT_TRUE(WIFEXITED(status)) << "killed by a signal instead of exiting";
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_GT(answered.load(), 0u);
  EXPECT_EQ(sent.load(), answered.load() + failed.load()) << "a frame was lost silently";
  EXPECT_EQ(sink_calls.load(), sent.load());
}

}  // namespace
}  // namespace skinserve::testing
