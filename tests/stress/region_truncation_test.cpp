// A client that truncates its shared-memory region while the server writes frames into it
// (issue 25): a write to a truncated shared mapping is SIGBUS, which would kill the server
// and every other client's streams with it. Against a real skinserve process: rounds of a
// stream of 400k-vertex frames into a region whose file a second thread keeps truncating
// and growing again, while a well-behaved client streams over gRPC on another connection.
// The server must stay alive and SERVING, every region frame must be answered (correct or
// FAILED_PRECONDITION naming the region), and every frame of the other stream correct.
#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <random>
#include <thread>

#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

constexpr uint32_t kVertices = 400'000;  // 4.8 MB a frame: writes take a while
constexpr int kRounds = 6;
constexpr int kFramesPerRound = 40;

// "still running", or how it ended (e.g. "killed by signal 7": a SIGBUS the guard missed).
std::string HowTheServerEnded(const ServerChild& server) {
  int status = 0;
  if (waitpid(server.pid(), &status, WNOHANG) != server.pid()) return "still running";
  if (WIFSIGNALED(status)) return fmt::format("killed by signal {}", WTERMSIG(status));
  return fmt::format("exited with {}", WEXITSTATUS(status));
}

TEST(RegionTruncationTest, AClientTruncatingItsRegionMidStreamCannotCrashTheServer) {
  char name[] = "/dev/shm/skinserve-truncate-XXXXXX";
  const std::string dir = mkdtemp(name);
  // Regions are served on the Unix socket (their owner is the client's process).
  const std::string socket = dir + "/grpc.sock";
  ServerChild server(
      {"--log-level", "warn", "--shm-dir", dir, "--threads", "2", "--listen", "unix:" + socket});
  ASSERT_TRUE(server.ready()) << server.error();
  client::SkinClient hostile(client::MakeChannel("unix:" + socket, 0));
  client::SkinClient neighbour(client::MakeChannel(server.target(), 1));
  const MeshArrays big = MakeSyntheticMesh({.vertex_count = kVertices, .influences = 4});
  auto big_id = hostile.Upload(big);
  ASSERT_TRUE(big_id.ok()) << big_id.status().ToString();
  const MeshArrays small = MakeSyntheticMesh({.vertex_count = 5000, .influences = 2, .seed = 9});
  auto small_mesh = Mesh::Create(small).value();
  auto small_id = neighbour.Upload(small);
  ASSERT_TRUE(small_id.ok());

  // The neighbour streams over gRPC the whole time; each answer checked.
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> neighbour_ok{0}, neighbour_bad{0};
  Status neighbour_status;
  std::thread neighbour_stream([&] {
    neighbour_status = client::StreamFrames(
        neighbour,
        {.mesh_id = small_id->mesh_id(),
         .backend = "simd",
         .frames = UINT64_MAX / 2,
         .window = 2,
         .stop = &stop},
        [](uint64_t f) { return MakeSyntheticPalette(77, 2, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          const bool good = r.status.ok() &&
                            CompareWithReference(*small_mesh, MakeSyntheticPalette(77, 2, r.frame),
                                                 r.positions, {})
                                .within_tolerance();
          (good ? neighbour_ok : neighbour_bad) += 1;
        });
  });

  const uint64_t stride = wire::RegionFrameBytes(kVertices, 1, VertexEncoding::kFloat32, false);
  uint64_t answered = 0, refused = 0, caught_mid_write = 0, other_errors = 0;
  std::string unexpected;
  for (int round = 0; round < kRounds; ++round) {
    auto region = client::SharedMemoryRegion::Create(
        client::SharedMemoryRegion::UniqueKey("truncated"), 2 * stride, dir);
    ASSERT_TRUE(region.ok()) << region.status().ToString();
    const std::string region_name = fmt::format("r{}", round);
    ASSERT_TRUE(hostile.RegisterRegion(region_name, **region).ok());
    // The client's own file: truncated to nothing and grown back, at random moments.
    std::atomic<bool> round_done{false};
    std::thread truncator([&, path = (*region)->path(), bytes = 2 * stride] {
      std::mt19937 rng(round);
      while (!round_done.load()) {
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 3000));
        if (truncate(path.c_str(), 0) != 0) break;
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 500));
        if (truncate(path.c_str(), static_cast<off_t>(bytes)) != 0) break;
      }
    });
    // The answers are never read here: the client's own mapping would fault as well.
    const std::string quoted = fmt::format("'{}'", region_name);
    const Status streamed = client::StreamFrames(
        hostile,
        {.mesh_id = big_id->mesh_id(),
         .backend = round % 2 == 0 ? "simd-openmp" : "opencl-zerocopy",
         .output = {.name = region_name, .region = region->get(), .stride = stride},
         .frames = kFramesPerRound,
         .window = 2},
        [](uint64_t f) { return MakeSyntheticPalette(77, 1, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          if (r.status.ok()) {
            ++answered;
          } else if (r.status.code() == StatusCode::kFailedPrecondition &&
                     r.status.message().find(quoted) != std::string::npos) {
            ++refused;
            caught_mid_write +=
                r.status.message().find("while the server wrote") != std::string::npos;
          } else {
            ++other_errors;
            unexpected = r.status.ToString();
          }
        });
    round_done.store(true);
    truncator.join();
    EXPECT_TRUE(streamed.ok()) << streamed.ToString() << " (round " << round << ", "
                               << (round % 2 == 0 ? "simd-openmp" : "opencl-zerocopy")
                               << "; the server: " << HowTheServerEnded(server) << ")";
    (void)hostile.UnregisterRegion(region_name);  // a broken region may be gone already
  }
  stop.store(true);
  neighbour_stream.join();
  EXPECT_TRUE(neighbour_status.ok()) << neighbour_status.ToString();

  std::printf(
      "[ region frames ] %lu answered, %lu refused (FAILED_PRECONDITION), %lu of them "
      "caught mid-write by the SIGBUS guard\n",
      static_cast<unsigned long>(answered), static_cast<unsigned long>(refused),
      static_cast<unsigned long>(caught_mid_write));
  EXPECT_TRUE(client::CheckHealth(neighbour.channel(), 5s).ok());
  EXPECT_EQ(answered + refused + other_errors, uint64_t{kRounds} * kFramesPerRound);
  EXPECT_EQ(other_errors, 0u) << unexpected;
  EXPECT_GT(refused, 0u) << "the truncations were never noticed";
  EXPECT_GT(neighbour_ok.load(), 0u);
  EXPECT_EQ(neighbour_bad.load(), 0u);
  EXPECT_EQ(server.Stop(SIGTERM), 0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace skinserve::testing
