// skinserve-load against real servers on loopback: what it reports must equal what the
// servers say they served (nothing lost, nothing counted twice).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <netinet/in.h>
#include <sys/socket.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

#include "load_process.h"
#include "report_files.h"
#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"
#include "workload.h"

namespace skinserve::testing {
namespace {

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

// --morph-targets: the synthetic mesh's targets are uploaded and every frame carries its
// active weights (a crowd's per instance), every answer checked against the float64
// reference of the morphed mesh. 'all' leaves out the backends without morph targets; one
// named anyway is refused the frames with weights (so they are on the wire), and frames
// without active weights (--morph-active 0) are the rest shape on any backend.
TEST(LoadIntegrationTest, MorphTargetsAreSentPerFrameAndCheckedAgainstTheReference) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  const std::string morph = " --target " + server.target() +
                            " --vertices 6000 --bones 3 --normals --morph-targets 16"
                            " --morph-coverage 0.2 --warmup 0 --check-every 1";
  int code = 0;
  const nlohmann::json closed =
      RunLoad(morph + " --backends all --morph-active 4 --streams 2 --frames 30", &code);
  EXPECT_EQ(code, 0);
  ASSERT_GE(closed["results"].size(), 4u);  // serial, openmp, simd, simd-openmp at least
  for (const auto& r : closed["results"]) {
    EXPECT_NE(r["backend"], "passthrough");
    EXPECT_EQ(r["checked"], 60) << r.dump();  // 2 streams x 30 frames, every one checked
  }
  const auto served = server.FramesServed();
  for (const auto& [backend, frames] : FramesReported(closed)) {
    EXPECT_EQ(frames, served.at(backend)) << backend;
  }
  const nlohmann::json crowd = RunLoad(
      morph + " --backends simd --morph-active 3 --instances 4 --rate 40 --duration 1", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(crowd["results"].size(), 1u);
  FramesReported(crowd);  // no errors, no mismatches
  EXPECT_GT(crowd["results"][0]["checked"], 10) << crowd.dump();
  const nlohmann::json refused =
      RunLoad(morph + " --backends passthrough --morph-active 4 --frames 10", &code);
  ASSERT_EQ(refused["results"].size(), 1u);
  EXPECT_EQ(refused["results"][0]["errors"].value("FAILED_PRECONDITION", 0), 20) << refused.dump();
  const nlohmann::json idle =
      RunLoad(morph + " --backends passthrough,serial --morph-active 0 --frames 10", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(idle["results"].size(), 2u);
  FramesReported(idle);
  for (const auto& r : idle["results"]) EXPECT_EQ(r["checked"], 20) << r.dump();
}

// --rest-encoding: the mesh is uploaded quantized and every answer is checked against the
// float64 reference of the values the quantized stream decodes to (the service test checks
// the stored encoding); a mesh the encoding cannot take is refused before any frame.
TEST(LoadIntegrationTest, RestEncodingIsAskedAtUploadAndCheckedOnTheDecodedMesh) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  const std::string common =
      " --target " + server.target() + " --vertices 5000 --bones 4 --normals --warmup 0";
  int code = 0;
  const nlohmann::json doc =
      RunLoad(common +
                  " --rest-encoding quantized8-weights --backends simd,simd-openmp,serial"
                  " --streams 2 --frames 12 --check-every 1",
              &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 3u) << doc.dump();
  FramesReported(doc);  // no errors, no mismatches
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["rest_encoding"], "quantized8-weights") << r.dump();
    EXPECT_EQ(r["checked"], 24) << r.dump();  // 2 streams x 12 frames, every one checked
  }
  const nlohmann::json refused = RunLoad(
      common + " --rest-encoding quantized16 --morph-targets 4 --backends simd --frames 2", &code);
  EXPECT_NE(code, 0);
  EXPECT_TRUE(refused.empty() || refused["results"].empty()) << refused.dump();
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

// A capacity probe that fails on errors prints the first message of each code under its
// row: the search's end then reads as the server's refusal (here --max-streams), not as
// the speed it reached. (A latency limit of 250 ms: the probes up to 3 streams must hold on
// a busy machine too, where a frame's p99 may pass 16.7 ms.)
TEST(LoadIntegrationTest, CapacityProbesSayWhyTheyFailedOnErrors) {
  ServerProcess server(0, {"--max-streams", "3"});
  ASSERT_TRUE(server.ready());
  int code = 0;
  std::string output;
  const nlohmann::json report =
      RunLoad("--target " + server.target() +
                  " --backends sse --vertices 2000 --capacity --capacity-max-streams 4"
                  " --duration 0.5 --warmup 0 --latency-limit-ms 250",
              &code, nullptr, &output);
  EXPECT_EQ(code, 0) << output;
  const std::regex refused(
      R"(\n +4 +4 .* no\n +errors: RESOURCE_EXHAUSTED x\d+, the first: .*--max-streams 3)");
  EXPECT_TRUE(std::regex_search(output, refused)) << output;
  EXPECT_NE(output.find("capacity: 3 characters"), std::string::npos) << output;
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

// A mesh the server loses mid-run (deleted here; evicted for another in the soak) goes again
// from the open loop, once per loss: the frames that met its absence fail NOT_FOUND (at most
// those in flight and those sent while it went again), and the schedule's later frames are
// answered and right.
TEST(LoadIntegrationTest, OpenLoopUploadsALostMeshAgainAndGoesOn) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  // The load client's mesh for these flags, to know its id (ids are content hashes): a
  // grid row's mesh is seeded --seed + vertices + bones.
  load::Workload workload =
      load::MakeWorkload(5000, 2, 77, /*normals=*/false, /*seed=*/3 + 5000 + 2);
  ASSERT_TRUE(load::ChooseRestEncoding(&workload, std::nullopt).ok());
  client::SkinClient client(client::MakeChannel(server.target()));
  const auto info = client.Upload(*workload.arrays, {.rest_encoding = workload.rest_encoding});
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  constexpr int kWindow = 4, kLosses = 2;
  int code = 0;
  nlohmann::json doc;
  std::thread run([&] {
    doc = RunLoad("--target " + server.target() +
                      " --backends sse --vertices 5000 --bones 2 --seed 3 --rate 100 --streams 1"
                      " --window 4 --duration 3 --warmup 0 --check-every 2",
                  &code);
  });
  for (int i = 0; i < kLosses; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    const auto deleted = client.DeleteMesh(info->mesh_id());
    EXPECT_TRUE(deleted.ok() && *deleted)
        << "the run's mesh was there to delete (loss " << i << ")";
  }
  run.join();
  ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
  const auto& r = doc["results"][0];
  const uint64_t not_found = r["errors"].value("NOT_FOUND", uint64_t{0});
  EXPECT_GE(not_found, 1u) << "the losses were met: " << r.dump();
  EXPECT_LE(not_found, uint64_t{kLosses * (2 * kWindow + 1)}) << r.dump();
  EXPECT_EQ(r["errors"].size(), 1u) << "NOT_FOUND only: " << r.dump();
  EXPECT_EQ(r["mismatches"], 0) << r.dump();
  EXPECT_EQ(r["frames"].get<uint64_t>() + not_found, r["sent"].get<uint64_t>()) << r.dump();
  // ~300 scheduled: nearly all of them answered, those after the last loss too.
  EXPECT_GE(r["frames"].get<uint64_t>(), 200u) << r.dump();
  EXPECT_GT(r["checked"].get<uint64_t>(), 100u) << r.dump();
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
  // Regions are served on the Unix socket: the load client talks to it, as a renderer would.
  const std::string socket = dir + "/grpc.sock";
  ServerProcess server(0, {"--shm-dir", dir, "--listen", "unix:" + socket});
  ASSERT_TRUE(server.ready());
  const std::string common = "--target unix:" + socket + " --shm-dir " + dir +
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
  // And the capacity search's probes over shm: at least one (a second only when one stream
  // held p99 within a frame, which a loaded 2-core machine may deny: timing, not counting).
  EXPECT_GE(shm_rows, 3u + 1u);
  client::SkinClient c(client::MakeChannel(server.target()));
  auto stats = c.GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->regions(), 0u) << "the load client unregisters its regions";
  EXPECT_GT(stats->region_frames(), 0u);
  std::filesystem::remove_all(dir);
}

// Each rate of a range is one row with rate x streams x duration frames scheduled (10% + 2:
// the first and last frames of a window fall either side of its ends, and this VM is
// noisy), every one of them counted by the server's frames counter too; the latency
// breakdown adds up; the CSV holds what the JSON does.
TEST(LoadIntegrationTest, RateRangeGivesOneRowPerRateWithTheFramesItShould) {
  const int metrics_port = FreePort();
  ServerProcess server(0, {"--metrics-listen", "127.0.0.1:" + std::to_string(metrics_port)});
  ASSERT_TRUE(server.ready());
  const std::string csv = UniqueJsonPath() + ".csv";
  std::string json;
  int code = 0;
  const double streams = 2, duration = 2;
  const nlohmann::json doc = RunLoad(
      "--target " + server.target() +
          " --backends sse --vertices 2000 --bones 2 --rate-range 10:30:10 --streams 2"
          " --duration 2 --warmup 0 --check-every 5 --percentile 90 --csv " +
          csv + " --metrics-url http://127.0.0.1:" + std::to_string(metrics_port) + "/metrics",
      &code, &json);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 3u) << doc.dump();
  double rate = 10;
  uint64_t total = 0;
  for (const auto& r : doc["results"]) {
    EXPECT_DOUBLE_EQ(r["rate"].get<double>(), rate);
    // The schedule offers rate x streams x duration frames; each is sent or, when --window
    // frames are still unanswered at its time (a loaded machine), dropped and counted.
    const double expected = rate * streams * duration;
    const double frames = r["frames"].get<double>();
    const double scheduled = r["sent"].get<double>() + r["dropped"].get<double>();
    EXPECT_LE(std::abs(scheduled - expected), 0.1 * expected + 2) << r.dump();
    EXPECT_EQ(r["frames"], r["sent"]) << "every frame sent was answered";
    EXPECT_EQ(r["arrivals"], "constant");
    EXPECT_EQ(r["percentile"], 90.0);
    EXPECT_DOUBLE_EQ(r["latency_ms"]["at_percentile"].get<double>(),
                     r["latency_ms"]["p90"].get<double>());
    // The server counted exactly the frames this row sent (its stream-opening probes ask
    // for passthrough and are left out), and the errors it answered: none.
    EXPECT_DOUBLE_EQ(r["server_metrics"]["frames"].get<double>(), frames) << r.dump();
    EXPECT_DOUBLE_EQ(r["server_metrics"]["frame_errors"].get<double>(), 0);
    // The server's own sums over those frames equal the client's sums of the per-frame
    // timings in the answers (microsecond rounding of the means aside).
    EXPECT_NEAR(r["server_metrics"]["queue_seconds_sum"].get<double>() * 1e3,
                r["server_ms"]["queue"].get<double>() * frames, 1e-3 * frames);
    EXPECT_NEAR(r["server_metrics"]["compute_seconds_sum"].get<double>() * 1e3,
                r["server_ms"]["compute"].get<double>() * frames, 1e-3 * frames);
    const auto& b = r["breakdown_ms"];
    double sum = 0;
    for (const char* part : {"send_lag", "queue", "skinning", "encode", "transport"}) {
      EXPECT_GE(b[part].get<double>(), 0) << part << ": " << r.dump();
      sum += b[part].get<double>();
    }
    EXPECT_LE(sum, b["latency_mean"].get<double>() * (1 + 1e-9) + 1e-9) << r.dump();
    EXPECT_GT(b["transport"].get<double>(), 0) << "loopback gRPC takes some time";
    total += r["frames"].get<uint64_t>();
    rate += 10;
  }
  EXPECT_EQ(total, server.FramesServed().at("sse"));
  load::ExpectCsvMatchesJson(csv, json);
}

// The server process's user + system CPU seconds as the kernel counts them
// (/proc/PID/stat's utime and stime, in clock ticks): a measure of the server's CPU that
// does not go through its /metrics.
double ProcessCpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(in, line);
  std::istringstream fields(line.substr(line.rfind(')') + 2));  // from field 3, state
  std::vector<std::string> field{std::istream_iterator<std::string>(fields), {}};
  EXPECT_GT(field.size(), 13u) << line;
  if (field.size() <= 13) return 0;
  return (std::stod(field[11]) + std::stod(field[12])) / sysconf(_SC_CLK_TCK);  // fields 14, 15
}

// Server CPU per frame (issue 41): over a run whose only server work outside the measured
// part is the upload and a few small calls, the reported CPU per frame x frames is the
// kernel's count of the server's CPU over the whole run, within 30% and 50 ms (the upload,
// the scrapes, 10 ms ticks at both ends of both counts); per character is per frame over
// the crowd's 2; over compute is per frame over the compute column. (Not asserted: that it
// is >= 1. The compute column is wall time on the compute thread, and on a busy machine
// that thread's preemption counts in it: simd measured 0.92 here under other builds.)
TEST(LoadIntegrationTest, ServerCpuPerFrameAgreesWithTheKernelsCountOfTheServersCpu) {
  MeteredServer metered;
  ServerProcess& server = metered.server();
  ASSERT_TRUE(server.ready());
  const double cpu_before = ProcessCpuSeconds(server.pid());
  std::string csv, json;
  int code = 0;
  const nlohmann::json doc = metered.RunLoad(
      "--backends simd --vertices 25000 --bones 2 --instances 2 --streams 1 --window 2"
      " --duration 2 --warmup 0",
      &code, &csv, &json);
  const double cpu_spent = ProcessCpuSeconds(server.pid()) - cpu_before;
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
  const auto& r = doc["results"][0];
  ASSERT_TRUE(r["server_cpu_us_per_frame"].is_number()) << r.dump();
  const double frames = r["frames"].get<double>();
  ASSERT_GT(frames, 0);
  // Closed loop with no warm-up: the server answered between the scrapes exactly the frames
  // the row counts, and per frame is the CPU over them.
  EXPECT_DOUBLE_EQ(r["server_frames"].get<double>(), frames) << r.dump();
  const double per_frame = r["server_cpu_us_per_frame"].get<double>();
  const double reported = r["server_cpu_seconds"].get<double>();
  EXPECT_NEAR(per_frame, reported * 1e6 / frames, 1e-6 * per_frame);
  EXPECT_LE(reported, cpu_spent * 1.3 + 0.05) << r.dump() << " kernel: " << cpu_spent << " s";
  EXPECT_GE(reported, cpu_spent * 0.7 - 0.05) << r.dump() << " kernel: " << cpu_spent << " s";
  EXPECT_DOUBLE_EQ(r["server_cpu_us_per_character"].get<double>(), per_frame / 2);
  EXPECT_NEAR(r["server_cpu_over_compute"].get<double>(),
              per_frame / (r["server_ms"]["compute"].get<double>() * 1e3), 1e-9);
  load::ExpectCsvMatchesJson(csv, json);

  // With a warm-up the first scrape comes as it ends: the server's frames between the scrapes
  // are the measured ones, give or take those answered while a scrape was on its way (a
  // quarter here: the warm-up's frames would double them).
  const nlohmann::json warm = metered.RunLoad(
      "--backends simd --vertices 25000 --streams 1 --window 2 --duration 1 --warmup 1", &code,
      nullptr, nullptr);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(warm["results"].size(), 1u) << warm.dump();
  const double warm_frames = warm["results"][0]["frames"].get<double>();
  EXPECT_LE(warm["results"][0]["server_frames"].get<double>(), warm_frames * 1.25 + 5)
      << warm.dump();

  // Without --metrics-url the columns are there and empty: no number is made up.
  const nlohmann::json bare =
      RunLoad("--target " + server.target() + " --backends simd --vertices 2000 --frames 5", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(bare["results"].size(), 1u) << bare.dump();
  for (const char* column : {"server_cpu_us_per_frame", "server_cpu_us_per_character",
                             "server_cpu_over_compute", "server_cpu_seconds", "server_frames"}) {
    EXPECT_TRUE(bare["results"][0].contains(column)) << column;
    EXPECT_TRUE(bare["results"][0][column].is_null()) << column << ": " << bare.dump();
  }
}

// Poisson arrivals as sent: the gaps between a stream's sends have the exponential's
// coefficient of variation (~1; the constant schedule's is ~0), and the frame count is the
// rate's within 4 standard deviations of a Poisson count (+2).
TEST(LoadIntegrationTest, PoissonArrivalsAreSentAsAPoissonProcess) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const std::string args = "--target " + server.target() +
                           " --backends sse --vertices 2000 --bones 2 --rate 40 --streams 2"
                           " --duration 3 --warmup 0 --seed 5 --arrivals ";
  const nlohmann::json poisson = RunLoad(args + "poisson", &code);
  EXPECT_EQ(code, 0);
  const nlohmann::json constant = RunLoad(args + "constant", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(poisson["results"].size(), 1u);
  ASSERT_EQ(constant["results"].size(), 1u);
  const auto& p = poisson["results"][0];
  const auto& c = constant["results"][0];
  EXPECT_EQ(p["arrivals"], "poisson");
  const double expected = 40 * 2 * 3;
  const double scheduled = p["sent"].get<double>() + p["dropped"].get<double>();
  EXPECT_LE(std::abs(scheduled - expected), 4 * std::sqrt(expected) + 2) << p.dump();
  // ~240 gaps: the CV's standard error is ~0.07; on a loaded machine sleeps overrun by
  // up to tens of ms (seen: constant 0.32 under the whole suite), hence the loose bounds.
  const double poisson_cv = p["send_gap_ms"]["cv"].get<double>();
  const double constant_cv = c["send_gap_ms"]["cv"].get<double>();
  EXPECT_GT(poisson_cv, 0.65) << p.dump();
  EXPECT_LT(poisson_cv, 1.5) << p.dump();
  EXPECT_NEAR(p["send_gap_ms"]["mean"].get<double>(), 25, 25 * 0.3) << p.dump();
  EXPECT_LT(constant_cv, 0.5) << c.dump();
  EXPECT_GT(poisson_cv, constant_cv + 0.3);
  EXPECT_NEAR(c["send_gap_ms"]["mean"].get<double>(), 25, 25 * 0.15) << c.dump();
  const double constant_scheduled = c["sent"].get<double>() + c["dropped"].get<double>();
  EXPECT_LE(std::abs(constant_scheduled - expected), 0.1 * expected + 2) << c.dump();
}

// The stability rule repeats windows until the last three agree or --max-trials ran; the
// row covers the last three windows. One trial applies no rule.
TEST(LoadIntegrationTest, StabilityRuleRepeatsWindowsAndSaysWhetherTheyAgreed) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const std::string args = "--target " + server.target() +
                           " --backends sse --vertices 2000 --bones 2 --rate 40 --streams 2"
                           " --duration 0.5 --warmup 0 ";
  const nlohmann::json ruled = RunLoad(args + "--max-trials 5 --stability-percentage 60", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(ruled["results"].size(), 1u);
  const auto& r = ruled["results"][0];
  ASSERT_TRUE(r["stable"].is_boolean()) << r.dump();
  const int trials = r["trials"].get<int>();
  EXPECT_GE(trials, 3);
  EXPECT_LE(trials, 5);
  if (trials < 5) {
    EXPECT_TRUE(r["stable"].get<bool>()) << "stopped early only when stable";
  }
  // Three windows of 0.5 s at 80 frames/s in all.
  // (each window ends at its last answer: later on a loaded machine)
  EXPECT_GE(r["seconds"].get<double>(), 1.4) << r.dump();
  EXPECT_LE(r["seconds"].get<double>(), 3.0) << r.dump();
  EXPECT_LE(std::abs(r["sent"].get<double>() + r["dropped"].get<double>() - 120), 0.1 * 120 + 2)
      << r.dump();

  const nlohmann::json once = RunLoad(args, &code);
  ASSERT_EQ(once["results"].size(), 1u);
  EXPECT_TRUE(once["results"][0]["stable"].is_null());
  EXPECT_EQ(once["results"][0]["trials"], 1);
  RunLoad("--target " + server.target() +
              " --backends sse --vertices 2000 --rate 40 --warmup 0 --max-trials 3 --frames 10",
          &code);
  EXPECT_EQ(code, 2) << "windows of --duration only";
}

TEST(LoadIntegrationTest, AnUnreachableMetricsUrlIsAnErrorNamingIt) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  const std::string command = std::string(SKINSERVE_LOAD_BINARY) + " --target " + server.target() +
                              " --backends sse --vertices 2000 --duration 0.2 --warmup 0"
                              " --metrics-url http://127.0.0.1:1/metrics 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[256];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) output += buffer;
  const int status = pclose(pipe);
  EXPECT_EQ(WEXITSTATUS(status), 1) << output;
  EXPECT_NE(output.find("--metrics-url http://127.0.0.1:1/metrics"), std::string::npos) << output;
}

TEST(LoadIntegrationTest, FailsWhenTheServerIsUnreachable) {
  int code = 0;
  RunLoad("--target 127.0.0.1:1 --duration 1", &code);
  EXPECT_NE(code, 0);
}

}  // namespace
}  // namespace skinserve::testing
