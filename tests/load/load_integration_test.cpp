// skinserve-load against real servers on loopback: what it reports must equal what the
// servers say they served (nothing lost, nothing counted twice).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {
namespace {

// A report file no other run of this test binary writes.
std::string UniqueJsonPath() {
  static int next = 0;
  return ::testing::TempDir() + "load-" + std::to_string(getpid()) + "-" + std::to_string(next++) +
         ".json";
}

// A skinserve child process on a loopback port, with the load client's view of it.
class ServerProcess {
 public:
  // `streams_per_connection`: the server's --max-streams-per-connection (0: its default).
  explicit ServerProcess(int streams_per_connection = 0, std::vector<std::string> extra = {})
      : child_(Arguments(streams_per_connection, std::move(extra))) {
    EXPECT_TRUE(child_.ready()) << child_.error();
  }
  const std::string& target() const { return child_.target(); }
  bool ready() const { return child_.ready(); }
  // Frames served per backend, from the server's own stats.
  std::map<std::string, uint64_t> FramesServed() const {
    client::SkinClient c(client::MakeChannel(target()));
    std::map<std::string, uint64_t> frames;
    auto stats = c.GetServerStats();
    EXPECT_TRUE(stats.ok()) << stats.status().ToString();
    if (stats.ok()) {
      for (const auto& b : stats->backends()) frames[b.id()] = b.frames();
    }
    return frames;
  }

 private:
  static std::vector<std::string> Arguments(int streams_per_connection,
                                            std::vector<std::string> extra) {
    std::vector<std::string> args = {"--log-level", "warn"};
    args.insert(args.end(), extra.begin(), extra.end());
    if (streams_per_connection > 0) {
      args.insert(args.end(),
                  {"--max-streams-per-connection", std::to_string(streams_per_connection)});
    }
    return args;
  }
  ServerChild child_;
};

nlohmann::json RunLoad(const std::string& args, int* exit_code) {
  const std::string json = UniqueJsonPath();
  const std::string command =
      std::string(SKINSERVE_LOAD_BINARY) + " " + args + " --json " + json + " > /dev/null";
  const int status = std::system(command.c_str());
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(json);
  nlohmann::json doc;
  if (in) in >> doc;
  return doc;
}

std::map<std::string, uint64_t> FramesReported(const nlohmann::json& doc) {
  std::map<std::string, uint64_t> frames;
  for (const auto& r : doc["results"]) {
    EXPECT_TRUE(r["errors"].empty()) << r.dump();
    EXPECT_EQ(r["mismatches"], 0) << r.dump();
    frames[r["backend"]] += r["frames"].get<uint64_t>();
  }
  return frames;
}

TEST(LoadIntegrationTest, ClosedLoopCountsEqualWhatTheServerServed) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const nlohmann::json doc =
      RunLoad("--target " + server.target() +
                  " --backends serial,sse-openmp,opencl-zerocopy,passthrough --vertices 20000"
                  " --bones 3 --streams 3 --window 3 --duration 1 --warmup 0 --check-every 5",
              &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 4u);
  for (const auto& r : doc["results"]) {
    EXPECT_GT(r["frames"], 0) << r.dump();
    EXPECT_GT(r["checked"], 0) << r.dump();
    for (const char* key : {"p50", "p90", "p99", "max"}) EXPECT_GT(r["latency_ms"][key], 0);
    EXPECT_GT(r["server_ms"]["compute"], 0);
    EXPECT_NEAR(
        r["speedup_over_serial"].get<double>(),
        r["frames_per_second"].get<double>() / doc["results"][0]["frames_per_second"].get<double>(),
        1e-9);
  }
  const auto served = server.FramesServed();
  for (const auto& [backend, frames] : FramesReported(doc)) {
    EXPECT_EQ(frames, served.at(backend)) << backend;
  }
}

TEST(LoadIntegrationTest, OpenLoopSendsOnScheduleAndCountsMatch) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const nlohmann::json doc =
      RunLoad("--target " + server.target() +
                  " --backends sse --vertices 5000 --bones 2 --rate 50 --streams 2 --duration 1"
                  " --warmup 0 --check-every 3",
              &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u);
  const auto& r = doc["results"][0];
  // 2 streams at 50 fps for ~1 s: about 100 frames scheduled, each sent or dropped.
  const uint64_t scheduled = r["sent"].get<uint64_t>() + r["dropped"].get<uint64_t>();
  EXPECT_GE(scheduled, 90u);
  EXPECT_LE(scheduled, 110u);
  EXPECT_EQ(r["frames"], r["sent"]) << "every frame sent was answered";
  EXPECT_EQ(FramesReported(doc).at("sse"), server.FramesServed().at("sse"));
}

// A stream whose call waits for a place on a full connection sends nothing in time: its
// frames are dropped, not left out (a capacity search would otherwise count characters
// that were never served). Spread over enough connections, every stream is served.
TEST(LoadIntegrationTest, OpenLoopCountsStreamsThatCouldNotOpenAsDropped) {
  ServerProcess server(/*streams_per_connection=*/2);
  ASSERT_TRUE(server.ready());
  const std::string args =
      " --backends sse --vertices 5000 --bones 2 --rate 50 --streams 4"
      " --duration 1 --warmup 0 --check-every 3 --target " +
      server.target();
  int code = 0;
  const nlohmann::json one = RunLoad(args + " --streams-per-connection 4", &code);
  ASSERT_EQ(one["results"].size(), 1u);
  const auto& crowded = one["results"][0];
  // 4 streams at 50 fps for ~1 s, 2 of them waiting the whole second: ~100 frames dropped.
  EXPECT_GE(crowded["dropped"].get<uint64_t>(), 80u) << crowded.dump();
  EXPECT_LE(crowded["sent"].get<uint64_t>(), 120u) << crowded.dump();
  EXPECT_EQ(crowded["frames"], crowded["sent"]) << "every frame sent was answered";

  const nlohmann::json two = RunLoad(args + " --streams-per-connection 2", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(two["results"].size(), 1u);
  const auto& spread = two["results"][0];
  EXPECT_GE(spread["sent"].get<uint64_t>(), 160u) << "all 4 streams sent: " << spread.dump();
  EXPECT_LT(spread["dropped"].get<uint64_t>(), 40u) << spread.dump();
  EXPECT_EQ(FramesReported(one).at("sse") + FramesReported(two).at("sse"),
            server.FramesServed().at("sse"));
}

TEST(LoadIntegrationTest, FrameCountClosedLoopMeasuresExactlyThatManyFramesPerStream) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  nlohmann::json doc = RunLoad("--target " + server.target() +
                                   " --backends sse --vertices 5000 --bones 2 --streams 3"
                                   " --window 4 --frames 40 --warmup 0 --check-every 4",
                               &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u);
  EXPECT_EQ(doc["results"][0]["frames"], 120) << doc.dump();
  EXPECT_EQ(doc["results"][0]["sent"], 120) << doc.dump();
  EXPECT_EQ(server.FramesServed().at("sse"), 120u) << "no warm-up: the server served just those";

  // With a warm-up the server serves more than is measured, and the measured count is exact.
  doc = RunLoad("--target " + server.target() +
                    " --backends sse --vertices 5000 --bones 2 --streams 3 --window 4"
                    " --frames 40 --warmup 0.3",
                &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u);
  EXPECT_EQ(doc["results"][0]["frames"], 120) << doc.dump();
  EXPECT_GT(server.FramesServed().at("sse"), 240u) << "warm-up frames went unserved";
}

TEST(LoadIntegrationTest, FrameCountOpenLoopSchedulesExactlyThatManyFramesPerStream) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const nlohmann::json doc =
      RunLoad("--target " + server.target() +
                  " --backends sse --vertices 5000 --bones 2 --rate 50 --streams 2 --frames 30"
                  " --warmup 0 --check-every 3",
              &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u);
  const auto& r = doc["results"][0];
  EXPECT_EQ(r["sent"].get<uint64_t>() + r["dropped"].get<uint64_t>(), 60u) << r.dump();
  EXPECT_EQ(r["frames"], r["sent"]) << "every frame sent was answered";
  EXPECT_EQ(server.FramesServed().at("sse"), r["frames"].get<uint64_t>());
}

TEST(LoadIntegrationTest, RoundRobinSpreadsStreamsOverTwoServers) {
  ServerProcess a, b;
  ASSERT_TRUE(a.ready() && b.ready());
  const std::string target = "ipv4:" + a.target() + "," + b.target();
  int code = 0;
  const nlohmann::json doc =
      RunLoad("--target " + target +
                  " --backends serial --vertices 10000 --bones 2 --streams 4 --window 2"
                  " --duration 1 --warmup 0 --check-every 7",
              &code);
  EXPECT_EQ(code, 0);
  const uint64_t from_a = a.FramesServed().at("serial"), from_b = b.FramesServed().at("serial");
  EXPECT_GT(from_a, 0u) << "round_robin left a replica idle";
  EXPECT_GT(from_b, 0u) << "round_robin left a replica idle";
  EXPECT_EQ(FramesReported(doc).at("serial"), from_a + from_b);
}

// Both data planes side by side, closed and open loop, crowds and a compact encoding, every
// answer checked against the float64 reference: the shared-memory rows count what the
// server wrote into the streams' regions, and the regions are gone afterwards.
TEST(LoadIntegrationTest, SharedMemoryDataPlaneInEveryModeCountsAndChecksEveryFrame) {
  char name[] = "/dev/shm/skinserve-load-XXXXXX";
  const std::string dir = mkdtemp(name);
  ServerProcess server(0, {"--shm-dir", dir});
  ASSERT_TRUE(server.ready());
  const std::string common = "--target " + server.target() + " --shm-dir " + dir +
                             " --data-planes grpc,shm --check-every 1 --warmup 0";
  int code = 0;
  const nlohmann::json closed =
      RunLoad(common +
                  " --backends simd-openmp,opencl --vertices 20000 --bones 3 --normals --streams 2"
                  " --window 3 --frames 15 --encoding snorm16 --instances 3",
              &code);
  EXPECT_EQ(code, 0);
  const auto served = server.FramesServed();
  for (const auto& [backend, frames] : FramesReported(closed)) {
    EXPECT_EQ(frames, served.at(backend)) << backend;
  }
  const nlohmann::json open = RunLoad(
      common + " --backends sse --vertices 5000 --bones 2 --rate 50 --streams 2 --frames 20",
      &code);
  EXPECT_EQ(code, 0);
  const nlohmann::json capacity = RunLoad(
      common + " --capacity --vertices 2000 --capacity-max-streams 2 --duration 0.5", &code);
  EXPECT_EQ(code, 0);
  uint64_t shm_rows = 0;
  for (const nlohmann::json* doc : {&closed, &open, &capacity}) {
    for (const auto& r : (*doc)["results"]) {
      EXPECT_GT(r["frames"], 0) << r.dump();
      if (r["data_plane"] == "shm") {
        ++shm_rows;
        EXPECT_GT(r["checked"], 0) << r.dump();
        EXPECT_TRUE(r["errors"].empty()) << r.dump();
        EXPECT_EQ(r["mismatches"], 0) << r.dump();
      }
    }
  }
  EXPECT_EQ(closed["results"].size(), 4u);
  EXPECT_EQ(open["results"].size(), 2u);
  EXPECT_GE(shm_rows, 3u + 2u);  // and the capacity probes
  client::SkinClient c(client::MakeChannel(server.target()));
  auto stats = c.GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->regions(), 0u) << "the load client unregisters its regions";
  EXPECT_GT(stats->region_frames(), 0u);
  std::filesystem::remove_all(dir);
}

TEST(LoadIntegrationTest, FailsWhenTheServerIsUnreachable) {
  int code = 0;
  RunLoad("--target 127.0.0.1:1 --duration 1", &code);
  EXPECT_NE(code, 0);
}

}  // namespace
}  // namespace skinserve::testing
