// scaleout-driver: frame accounting for the scale-out fault test.
//
// Streams frames of one synthetic mesh through the client library's StreamFrames over one
// target (e.g. a round_robin ipv4: list of replicas) for a while, checks every answered
// frame against the float64 reference, and accounts for every frame sent: answered
// correctly, answered wrong, or reported failed (by status code). skinserve-load checks
// correctness too, but its closed-loop report does not count frames sent, which is what
// "none lost silently" needs.
//
// Prints one JSON object; exits 0 when sent == answered + failed (per stream and in
// total), the sink saw each frame the summary counted, and no answer was wrong.
//
// With --clip-frames N each client streams clips of N frames, one StreamSkin call per clip,
// as an animation client would: every new stream is placed by the channel's round_robin
// over the replicas it knows at that moment (scaleout.grow: a replica added mid-run).
//
// usage: scaleout-driver --target T [--backend sse] [--streams 6] [--window 4]
//                        [--seconds 8] [--vertices 20000] [--clip-frames 0 (one stream)]
//                        [--tls-ca F [--tls-cert F --tls-key F] [--tls-server-name N]]
//                        [--keepalive-seconds 10] [--keepalive-timeout-seconds 5]
//                        [--deadline-seconds 30] [--stream-idle-seconds 30]
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/model/mesh.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace {

using namespace skinserve;

struct Options {
  std::string target;
  std::string backend = "sse";
  int streams = 6;
  int window = 4;
  double seconds = 8;
  uint32_t vertices = 20'000;
  uint64_t clip_frames = 0;  // 0: one stream per client for the whole run
  client::TlsFiles tls;
  double keepalive_seconds = 10, keepalive_timeout_seconds = 5;
  double deadline_seconds = 30, stream_idle_seconds = 30;
};

Options Parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--target")
      o.target = value;
    else if (key == "--backend")
      o.backend = value;
    else if (key == "--streams")
      o.streams = std::stoi(value);
    else if (key == "--window")
      o.window = std::stoi(value);
    else if (key == "--seconds")
      o.seconds = std::stod(value);
    else if (key == "--vertices")
      o.vertices = static_cast<uint32_t>(std::stoul(value));
    else if (key == "--clip-frames")
      o.clip_frames = std::stoull(value);
    else if (key == "--tls-ca")
      o.tls.ca = value;
    else if (key == "--tls-cert")
      o.tls.cert = value;
    else if (key == "--tls-key")
      o.tls.key = value;
    else if (key == "--tls-server-name")
      o.tls.server_name = value;
    else if (key == "--keepalive-seconds")
      o.keepalive_seconds = std::stod(value);
    else if (key == "--keepalive-timeout-seconds")
      o.keepalive_timeout_seconds = std::stod(value);
    else if (key == "--deadline-seconds")
      o.deadline_seconds = std::stod(value);
    else if (key == "--stream-idle-seconds")
      o.stream_idle_seconds = std::stod(value);
    else {
      fmt::print(stderr, "unknown option {}\n", key);
      std::exit(2);
    }
  }
  if (o.target.empty() || argc % 2 == 0) {
    fmt::print(stderr,
               "usage: scaleout-driver --target T [--backend B] [--streams N] [--window W] "
               "[--seconds S] [--vertices V] [--clip-frames N] [--tls-ca F [--tls-cert F "
               "--tls-key F] [--tls-server-name N]] [--keepalive-seconds S] "
               "[--keepalive-timeout-seconds S] [--deadline-seconds S] "
               "[--stream-idle-seconds S]\n");
    std::exit(2);
  }
  return o;
}

struct Tally {
  std::mutex mutex;
  uint64_t sent = 0, answered = 0, failed = 0, reconnects = 0, reuploads = 0;  // summaries
  uint64_t sink_ok = 0, sink_failed = 0, wrong = 0;                            // the sink's view
  uint64_t unbalanced_streams = 0;  // streams whose own sent != answered + failed
  uint64_t stream_calls = 0;        // StreamFrames calls (clips)
  std::map<std::string, uint64_t> failed_by_code, stream_status;
};

}  // namespace

int main(int argc, char** argv) {
  const Options o = Parse(argc, argv);
  constexpr uint32_t kJoints = 77;
  constexpr uint64_t kSeed = 7;
  auto arrays = std::make_shared<const MeshArrays>(MakeSyntheticMesh(
      {.vertex_count = o.vertices, .influences = 2, .joint_count = kJoints, .seed = kSeed}));
  auto mesh = Mesh::Create(*arrays);
  if (!mesh.ok()) {
    fmt::print(stderr, "error: {}\n", mesh.status().ToString());
    return 2;
  }
  std::vector<std::vector<float>> palettes;
  for (uint64_t f = 0; f < 16; ++f) palettes.push_back(MakeSyntheticPalette(kJoints, kSeed, f));
  auto palette = [&](uint64_t frame) { return palettes[frame % palettes.size()]; };

  auto channel_options = client::ChannelOptionsFromFiles(o.tls);
  if (!channel_options.ok()) {
    fmt::print(stderr, "error: {}\n", channel_options.status().ToString());
    return 2;
  }
  const auto ms = [](double seconds) {
    return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
  };
  channel_options->keepalive_time = ms(o.keepalive_seconds);
  channel_options->keepalive_timeout = ms(o.keepalive_timeout_seconds);
  const client::CallLimits limits{.deadline = ms(o.deadline_seconds),
                                  .stream_idle = ms(o.stream_idle_seconds)};
  client::SkinClient uploader(client::MakeChannel(o.target, *channel_options), limits);
  if (Status s = client::WaitUntilServing(uploader.channel(), std::chrono::seconds(10)); !s.ok()) {
    fmt::print(stderr, "error: {}: {}\n", o.target, s.ToString());
    if (const std::string hint = client::ConnectionHint(s); !hint.empty()) {
      fmt::print(stderr, "hint: {}\n", hint);
    }
    return 2;
  }
  auto info = uploader.Upload(*arrays);
  if (!info.ok()) {
    fmt::print(stderr, "error: upload: {}\n", info.status().ToString());
    return 2;
  }
  const std::string mesh_id = info->mesh_id();

  Tally tally;
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  for (int s = 0; s < o.streams; ++s) {
    threads.emplace_back([&] {
      // One channel per stream, as separate clients would have: round_robin spreads them.
      client::SkinClient client(client::MakeChannel(o.target, *channel_options), limits);
      client.Remember(mesh_id, arrays);
      const uint64_t clip = o.clip_frames > 0 ? o.clip_frames : UINT64_MAX / 2;
      client::StreamSummary summary;
      Status status;
      uint64_t calls = 0, unbalanced = 0;
      for (uint64_t first = 0; !stop.load(); first += clip) {
        client::StreamOptions options{.mesh_id = mesh_id,
                                      .backend = o.backend,
                                      .first_frame = first,
                                      .frames = clip,
                                      .window = o.window,
                                      .stop = &stop};
        client::StreamSummary one;
        status = client::StreamFrames(
            client, options, palette,
            [&](client::FrameResult& r, std::chrono::nanoseconds) {
              bool ok = r.status.ok(), right = true;
              if (ok) {
                const Deviation d = CompareWithReference(**mesh, palette(r.frame), r.positions, {});
                right = d.within_tolerance();
              }
              std::lock_guard lock(tally.mutex);
              if (!ok) {
                ++tally.sink_failed;
                ++tally.failed_by_code[StatusCodeName(r.status.code())];
                // The first few reasons, for whoever reads a failed run's log.
                if (tally.sink_failed <= 5) {
                  fmt::print(stderr, "frame {} failed: {}\n", r.frame, r.status.ToString());
                }
              } else {
                ++tally.sink_ok;
                tally.wrong += !right;
              }
            },
            &one);
        summary.sent += one.sent;
        summary.answered += one.answered;
        summary.failed += one.failed;
        summary.reconnects += one.reconnects;
        summary.reuploads += one.reuploads;
        unbalanced += one.sent != one.answered + one.failed;
        ++calls;
        if (!status.ok()) break;
      }
      std::lock_guard lock(tally.mutex);
      tally.sent += summary.sent;
      tally.answered += summary.answered;
      tally.failed += summary.failed;
      tally.reconnects += summary.reconnects;
      tally.reuploads += summary.reuploads;
      tally.unbalanced_streams += unbalanced;
      tally.stream_calls += calls;
      ++tally.stream_status[StatusCodeName(status.code())];
    });
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(o.seconds));
  stop.store(true);
  for (auto& t : threads) t.join();

  auto to_json = [](const std::map<std::string, uint64_t>& m) {
    std::string out = "{";
    for (const auto& [k, v] : m)
      out += fmt::format("{}\"{}\": {}", out.size() > 1 ? ", " : "", k, v);
    return out + "}";
  };
  const bool balanced =
      tally.sent == tally.answered + tally.failed && tally.unbalanced_streams == 0;
  const bool sink_agrees = tally.sink_ok == tally.answered && tally.sink_failed == tally.failed;
  fmt::print(
      "{{\"backend\": \"{}\", \"streams\": {}, \"sent\": {}, \"answered\": {}, \"failed\": {}, "
      "\"wrong\": {}, \"checked\": {}, \"reconnects\": {}, \"reuploads\": {}, \"clips\": {}, "
      "\"failed_by_code\": {}, \"stream_status\": {}, \"balanced\": {}, \"sink_agrees\": {}}}\n",
      o.backend, o.streams, tally.sent, tally.answered, tally.failed, tally.wrong, tally.sink_ok,
      tally.reconnects, tally.reuploads, tally.stream_calls, to_json(tally.failed_by_code),
      to_json(tally.stream_status), balanced, sink_agrees);
  return balanced && sink_agrees && tally.wrong == 0 && tally.sent > 0 ? 0 : 1;
}
