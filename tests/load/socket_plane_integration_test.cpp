// skinserve-load --data-planes socket against a real server with its frame socket: frames and
// ticks travel on the socket into the load client's shared-memory regions, in open loop
// (--rate) and closed loop (the window kept full), every answer is checked against the
// float64 reference, and the server counts the socket's requests.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <string>

#include "load_process.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {
namespace {

// A server on a Unix socket with its frame socket and regions in a fresh folder of /dev/shm.
class SocketPlaneTest : public ::testing::Test {
 protected:
  SocketPlaneTest()
      : dir_(MakeDir()),
        server_(0, {"--shm-dir", dir_, "--listen", "unix:" + dir_ + "/grpc.sock", "--frame-socket",
                    dir_ + "/frames.sock"}) {}
  ~SocketPlaneTest() override { std::filesystem::remove_all(dir_); }
  void SetUp() override { ASSERT_TRUE(server_.ready()); }

  // skinserve-load over the socket plane, every answer checked, with `args`.
  nlohmann::json RunSocket(const std::string& args, int* code, std::string* output = nullptr) {
    return RunLoad(fmt::format("--target unix:{0}/grpc.sock --shm-dir {0} --data-planes socket "
                               "--frame-socket {0}/frames.sock --check-every 1 --warmup 0 {1}",
                               dir_, args),
                   code, nullptr, output);
  }
  // RunSocket, then what every run must show: exit 0, `rows` rows, each on the socket plane
  // with frames answered, none with errors or mismatches.
  nlohmann::json RunChecked(const std::string& args, std::size_t rows) {
    int code = 0;
    nlohmann::json doc = RunSocket(args, &code);
    EXPECT_EQ(code, 0) << doc.dump();
    EXPECT_EQ(doc["results"].size(), rows) << doc.dump();
    FramesReported(doc);
    for (const auto& r : doc["results"]) {
      EXPECT_EQ(r["data_plane"], "socket") << r.dump();
      EXPECT_GT(r["frames"].get<uint64_t>(), 0u) << r.dump();
    }
    return doc;
  }
  uint64_t SocketRequests() {
    client::SkinClient c(client::MakeChannel(server_.target()));
    auto stats = c.GetServerStats();
    EXPECT_TRUE(stats.ok()) << stats.status().ToString();
    return stats.ok() ? stats->frame_socket_requests() : 0;
  }

  static std::string MakeDir() {
    char name[] = "/dev/shm/skinserve-socket-load-XXXXXX";
    return mkdtemp(name);
  }
  const std::string dir_;
  ServerProcess server_;
};

// Open loop, single characters with normals on two backends: every frame sent is answered on
// the socket, checked and right; the report names the plane; the server counts the socket's
// requests (each stream's probe of its mesh too).
TEST_F(SocketPlaneTest, OpenLoopFramesAreAnsweredOnTheSocketAndRight) {
  const nlohmann::json doc = RunChecked(
      "--backends serial,simd --vertices 2000 --bones 2 --normals --rate 40 --streams 2 "
      "--frames 6",
      2);
  uint64_t frames = 0;
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["sent"].get<uint64_t>() + r["dropped"].get<uint64_t>(), 12u) << r.dump();
    EXPECT_EQ(r["frames"], r["sent"]) << "every frame sent was answered: " << r.dump();
    EXPECT_EQ(r["checked"], r["frames"]) << r.dump();
    frames += r["frames"].get<uint64_t>();
  }
  EXPECT_GE(SocketRequests(), frames) << "the frames went over the socket";
}

// Open loop, ticks of 3 distinct meshes: every character of every tick answered into its
// range of the region and right.
TEST_F(SocketPlaneTest, OpenLoopTicksAreAnsweredOnTheSocketAndRight) {
  const nlohmann::json doc = RunChecked(
      "--backends simd --vertices 1500 --bones 3 --characters-per-tick 3 --rate 30 --streams 2 "
      "--frames 5",
      1);
  ASSERT_EQ(doc["results"].size(), 1u);
  const auto& r = doc["results"][0];
  EXPECT_EQ(r["characters_per_tick"], 3) << r.dump();
  EXPECT_EQ(r["frames"], r["sent"]) << r.dump();
  EXPECT_EQ(r["checked"].get<uint64_t>(), 3 * r["frames"].get<uint64_t>()) << r.dump();
  EXPECT_GE(SocketRequests(), r["frames"].get<uint64_t>());
}

// Closed loop (no --rate), single characters and ticks: frames go as answers free the
// window's slots for --duration, none dropped or counted late, every one answered on the
// socket and right.
TEST_F(SocketPlaneTest, ClosedLoopSendsAsAnswersComeForTheDuration) {
  for (const char* ticks : {"", "--characters-per-tick 2"}) {
    SCOPED_TRACE(ticks);
    const uint64_t before = SocketRequests();
    const nlohmann::json doc =
        RunChecked(fmt::format("--backends simd --vertices 1500 --bones 2 --streams 2 --window 3 "
                               "--duration 1 {}",
                               ticks),
                   1);
    ASSERT_EQ(doc["results"].size(), 1u);
    const auto& r = doc["results"][0];
    EXPECT_EQ(r["rate"], 0) << "closed loop: " << r.dump();
    EXPECT_GT(r["frames"].get<uint64_t>(), 20u) << "a second of 2 streams: " << r.dump();
    EXPECT_EQ(r["dropped"], 0) << r.dump();
    EXPECT_EQ(r["late"], 0) << r.dump();
    EXPECT_GT(r["checked"].get<uint64_t>(), 0u) << r.dump();
    EXPECT_GE(SocketRequests() - before, r["frames"].get<uint64_t>());
  }
}

// The plane without --frame-socket, and a closed loop over it bounded by --frames, are
// refused before anything runs, naming what they need.
TEST_F(SocketPlaneTest, TheSocketPlaneWithoutItsPathOrWithFramesInClosedLoopIsRefused) {
  int code = 0;
  std::string output;
  (void)RunLoad(fmt::format("--target unix:{0}/grpc.sock --shm-dir {0} --data-planes socket "
                            "--rate 10 --frames 2 --backends simd --vertices 500",
                            dir_),
                &code, nullptr, &output);
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find("--frame-socket PATH"), std::string::npos) << output;
  (void)RunSocket("--frames 4 --backends simd --vertices 500", &code, &output);
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find("closed loop for --duration: not with --frames"), std::string::npos)
      << output;
}

}  // namespace
}  // namespace skinserve::testing
