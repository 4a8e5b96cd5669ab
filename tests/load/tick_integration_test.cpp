// Ticks (issue 41) through the clients that drive them against a real server: skinserve-load
// --characters-per-tick (every character of every tick against its own mesh's float64
// reference, over both data planes, counts in characters) and skinserve-cli tick (each
// character's outcome, a bad one named, the exit status saying so; over gRPC and over the
// frame socket).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "load_process.h"
#include "report_files.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {
namespace {

// A server on a Unix socket with regions in a fresh folder of /dev/shm (the shm data plane),
// and its TCP port.
class ShmServer {
 public:
  ShmServer()
      : dir_(MakeDir()),
        socket_(dir_ + "/grpc.sock"),
        server_(0, {"--shm-dir", dir_, "--listen", "unix:" + socket_}) {}
  ~ShmServer() { std::filesystem::remove_all(dir_); }
  ServerProcess& server() { return server_; }
  // The load client's options to reach the server over its socket with regions in `dir_`.
  std::string LoadTarget() const { return "--target unix:" + socket_ + " --shm-dir " + dir_; }
  std::string socket_target() const { return "unix:" + socket_; }
  const std::string& dir() const { return dir_; }

 private:
  static std::string MakeDir() {
    char name[] = "/dev/shm/skinserve-tick-XXXXXX";
    return mkdtemp(name);
  }
  std::string dir_, socket_;
  ServerProcess server_;
};

// Ticks over both data planes of a fresh ShmServer, closed loop unless told otherwise,
// every character checked.
class TickLoadTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(shm_.server().ready()); }
  // skinserve-load with ticks of `characters` characters and `args`.
  nlohmann::json RunTicks(int characters, const std::string& args, int* code,
                          std::string* output = nullptr) {
    return RunLoad(fmt::format("{} --data-planes grpc,shm --check-every 1 --warmup 0"
                               " --characters-per-tick {} {}",
                               shm_.LoadTarget(), characters, args),
                   code, nullptr, output);
  }
  ShmServer shm_;
};

// Ticks of 4 characters (4 distinct meshes, each a crowd of 2 in snorm16 with normals) on
// three backends over both data planes, closed loop: every character of every tick is
// checked against its own mesh's reference and agrees; the server skinned each character as
// a frame of its backend; the 4 meshes were uploaded once each.
TEST_F(TickLoadTest, EveryCharacterOfEveryTickMatchesItsReferenceOverBothPlanes) {
  int code = 0;
  const nlohmann::json doc =
      RunTicks(4,
               "--backends serial,simd-openmp,opencl --vertices 3000 --bones 3 --normals"
               " --streams 2 --window 2 --frames 5 --encoding snorm16 --instances 2",
               &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 6u) << doc.dump();
  std::map<std::string, uint64_t> characters;
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["characters_per_tick"], 4) << r.dump();
    EXPECT_EQ(r["frames"], 10) << "2 streams x 5 ticks: " << r.dump();
    EXPECT_EQ(r["checked"], 40) << "every character of every tick: " << r.dump();
    EXPECT_EQ(r["mismatches"], 0) << r.dump();
    EXPECT_TRUE(r["errors"].empty()) << r.dump();
    EXPECT_NEAR(r["characters_per_second"].get<double>(),
                r["frames_per_second"].get<double>() * 4 * 2, 1e-6)
        << r.dump();
    characters[r["backend"]] += r["frames"].get<uint64_t>() * 4;
  }
  const auto served = shm_.server().FramesServed();
  for (const auto& [backend, count] : characters) EXPECT_EQ(count, served.at(backend)) << backend;
  client::SkinClient c(client::MakeChannel(shm_.server().target()));
  auto stats = c.GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->meshes(), 4u) << "4 distinct meshes, each uploaded once";
  EXPECT_EQ(stats->regions(), 0u) << "the load client unregisters its regions";
  EXPECT_GT(stats->region_frames(), 0u);
}

// Open loop with morph targets (each character its own weights per tick): every tick sent
// is answered, every character checked and right, over both planes.
TEST_F(TickLoadTest, OpenLoopTicksWithMorphWeightsAreAnsweredAndRight) {
  int code = 0;
  const nlohmann::json doc =
      RunTicks(4,
               "--backends simd --vertices 2000 --bones 2 --morph-targets 8 --morph-active 3"
               " --rate 30 --streams 2 --frames 6",
               &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 2u) << doc.dump();
  FramesReported(doc);  // no errors, no mismatches
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["sent"].get<uint64_t>() + r["dropped"].get<uint64_t>(), 12u) << r.dump();
    EXPECT_EQ(r["frames"], r["sent"]) << "every tick sent was answered: " << r.dump();
    EXPECT_EQ(r["checked"].get<uint64_t>(), 4 * r["frames"].get<uint64_t>()) << r.dump();
    EXPECT_GT(r["frames"], 0) << r.dump();
  }
}

// --capacity with ticks counts characters: every probe row holds streams x 3 characters,
// and the verdict of each data plane is its streams x 3.
TEST_F(TickLoadTest, CapacityCountsCharactersOfTicks) {
  int code = 0;
  std::string output;
  RunTicks(3, "--capacity --vertices 2000 --capacity-max-streams 2 --duration 0.5", &code, &output);
  EXPECT_EQ(code, 0) << output;
  const std::regex probe(R"(^\s+(\d+)\s+(\d+)\s+\d+\.\d)");
  const std::regex verdict(R"(^capacity: (\d+) characters \((\d+) streams x 3 characters a tick)");
  int probes = 0, verdicts = 0;
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    std::smatch m;
    if (std::regex_search(line, m, probe)) {
      ++probes;
      EXPECT_EQ(std::stoi(m[2]), 3 * std::stoi(m[1])) << line;
    } else if (std::regex_search(line, m, verdict)) {
      ++verdicts;
      EXPECT_EQ(std::stoi(m[1]), 3 * std::stoi(m[2])) << line;
    }
  }
  EXPECT_GE(probes, 2) << output;  // at least one stream on each plane
  EXPECT_EQ(verdicts, 2) << output;
}

// Server CPU per character divides by the tick's characters: the server counts each
// character as a frame (server_frames = ticks x 4), per frame is per tick, per character a
// quarter of it; the CSV carries what the JSON does, characters_per_tick included.
TEST(TickLoadMetricsTest, ServerCpuPerCharacterDividesByTheTicksCharacters) {
  MeteredServer metered;
  ASSERT_TRUE(metered.server().ready());
  std::string csv, json;
  int code = 0;
  const nlohmann::json doc = metered.RunLoad(
      "--characters-per-tick 4 --backends simd --vertices 5000 --streams 1 --window 2"
      " --frames 20 --warmup 0",
      &code, &csv, &json);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
  const auto& r = doc["results"][0];
  EXPECT_EQ(r["frames"], 20) << r.dump();
  EXPECT_DOUBLE_EQ(r["server_frames"].get<double>(), 80) << "characters: " << r.dump();
  ASSERT_TRUE(r["server_cpu_us_per_frame"].is_number()) << r.dump();
  const double per_tick = r["server_cpu_us_per_frame"].get<double>();
  EXPECT_NEAR(per_tick, r["server_cpu_seconds"].get<double>() * 1e6 / 20, 1e-6 * per_tick);
  EXPECT_DOUBLE_EQ(r["server_cpu_us_per_character"].get<double>(), per_tick / 4);
  load::ExpectCsvMatchesJson(csv, json);
}

std::string Cli(const std::string& target, const std::string& args, int* code) {
  return RunCommand(std::string(SKINSERVE_CLI_BINARY) + " --target " + target + " tick " + args,
                    code);
}

// skinserve-cli tick: a tick of distinct synthetic meshes and a glTF character, each
// answered and within its reference; with a mesh the server does not know, that character
// alone fails, named with NOT_FOUND, the others are still answered, and the exit status is 1.
TEST(TickCliTest, PrintsEachCharacterAndFailsTheExitStatusOnABadOne) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const std::string good = Cli(server.target(),
                               "--synthetic 2 --vertices 3000 --normals --backend simd " +
                                   std::string(SKINSERVE_TEST_ASSETS_DIR) + "/CesiumMan.glb",
                               &code);
  EXPECT_EQ(code, 0) << good;
  EXPECT_NE(good.find("character 0 (synthetic seed 1): 3000 vertices"), std::string::npos) << good;
  EXPECT_NE(good.find("character 1 (synthetic seed 2): 3000 vertices"), std::string::npos) << good;
  EXPECT_NE(good.find("character 2 ("), std::string::npos) << good;
  EXPECT_EQ(good.find("MISMATCH"), std::string::npos) << good;
  EXPECT_NE(good.find("tick 0: 3 characters, 3 answered, 0 failed"), std::string::npos) << good;

  const std::string unknown(64, '0');
  const std::string bad =
      Cli(server.target(), "--synthetic 2 --vertices 3000 --frame 7 --mesh-id " + unknown, &code);
  EXPECT_EQ(code, 1) << bad;
  EXPECT_NE(bad.find("character 0 (synthetic seed 1): 3000 vertices"), std::string::npos) << bad;
  EXPECT_NE(bad.find("character 1 (synthetic seed 2): 3000 vertices"), std::string::npos) << bad;
  EXPECT_NE(bad.find("character 2 (mesh " + unknown + "): NOT_FOUND"), std::string::npos) << bad;
  EXPECT_NE(bad.find("tick 7: 3 characters, 2 answered, 1 failed"), std::string::npos) << bad;
}

// Over shared memory each character is written into its own range of the command's region,
// read there and checked against its reference; the region is unregistered afterwards.
TEST(TickCliTest, WritesEachCharacterIntoItsOwnRangeOfARegion) {
  ShmServer shm;
  ASSERT_TRUE(shm.server().ready());
  int code = 0;
  const std::string out = Cli(shm.socket_target(),
                              "--synthetic 3 --vertices 2000 --normals --backend simd-openmp "
                              "--shared-memory --shm-dir " +
                                  shm.dir(),
                              &code);
  EXPECT_EQ(code, 0) << out;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NE(out.find(fmt::format("character {} (synthetic seed {}): 2000 vertices in the region",
                                   i, i + 1)),
              std::string::npos)
        << out;
  }
  EXPECT_EQ(out.find("MISMATCH"), std::string::npos) << out;
  EXPECT_NE(out.find("tick 0: 3 characters, 3 answered, 0 failed"), std::string::npos) << out;
  client::SkinClient c(client::MakeChannel(shm.server().target()));
  auto stats = c.GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->regions(), 0u) << "the command unregisters its region";
  EXPECT_GT(stats->region_frames(), 0u);
}

// --frame-socket: the same tick over the server's frame socket, region characters in their
// ranges (the region registered over gRPC on the unix: target by the same process), a mesh
// the server does not know failing alone; the server counts the socket's request.
TEST(TickCliTest, SendsTheTickOverTheFrameSocket) {
  char name[] = "/dev/shm/skinserve-tick-XXXXXX";
  const std::string dir = mkdtemp(name);
  {
    ServerProcess server(0, {"--shm-dir", dir, "--listen", "unix:" + dir + "/grpc.sock",
                             "--frame-socket", dir + "/frames.sock"});
    ASSERT_TRUE(server.ready());
    const std::string unknown(64, '0');
    int code = 0;
    const std::string out =
        Cli("unix:" + dir + "/grpc.sock",
            "--synthetic 2 --vertices 2000 --normals --backend simd "
            "--shared-memory --shm-dir " +
                dir + " --frame-socket " + dir + "/frames.sock --frame 4 " + "--mesh-id " + unknown,
            &code);
    EXPECT_EQ(code, 1) << out;
    for (int i = 0; i < 2; ++i) {
      EXPECT_NE(out.find(fmt::format(
                    "character {} (synthetic seed {}): 2000 vertices in the region", i, i + 1)),
                std::string::npos)
          << out;
    }
    EXPECT_NE(out.find("character 2 (mesh " + unknown + "): NOT_FOUND"), std::string::npos) << out;
    EXPECT_EQ(out.find("MISMATCH"), std::string::npos) << out;
    EXPECT_NE(out.find("tick 4: 3 characters, 2 answered, 1 failed"), std::string::npos) << out;
    client::SkinClient c(client::MakeChannel(server.target()));
    auto stats = c.GetServerStats();
    ASSERT_TRUE(stats.ok());
    EXPECT_EQ(stats->frame_socket_requests(), 1u) << "the tick went over the socket";
    EXPECT_EQ(stats->regions(), 0u) << "the command unregisters its region";

    const std::string none =
        Cli("unix:" + dir + "/grpc.sock",
            "--synthetic 1 --vertices 500 --frame-socket " + dir + "/none.sock", &code);
    EXPECT_NE(code, 0) << none;
    EXPECT_NE(none.find("none.sock"), std::string::npos) << none;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace skinserve::testing
