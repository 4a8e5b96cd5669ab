// skinserve-load: what each backend delivers through the real service.
//   closed loop   --streams N --window W --duration S (or --frames N per stream)
//   open loop     --rate FPS (per stream), late and dropped frames reported
//   --sweep paper the paper's grid over every backend, tables 2 and 3 layout
//   --capacity    the most concurrent 60 fps streams held with p99 within one frame
#include <fmt/format.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>

#include "load_report.h"
#include "load_runner.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::load {
namespace {

struct Options {
  RunConfig run;
  std::string backends = "all";
  uint32_t vertices = 100'000, bones = 2, joints = 77;
  bool normals = false;
  std::string method = "linear";
  uint64_t seed = 1;
  std::string mesh;  // a glTF file instead of the synthetic mesh
  int primitive = 0;
  std::string sweep;
  bool capacity = false;
  int capacity_max_streams = 64;
  std::string json, csv, plot;
};

// A progress bar on a terminal; nothing when stderr is not one.
Progress MakeProgress(const std::string& label) {
  if (!isatty(STDERR_FILENO)) return nullptr;
  return [label](double fraction) {
    const int filled = static_cast<int>(fraction * 30);
    fmt::print(stderr, "\r{:<40} [{}{}] {:3.0f}%", label, std::string(filled, '#'),
               std::string(30 - filled, ' '), fraction * 100);
    if (fraction >= 1.0) fmt::print(stderr, "\r{:80}\r", "");
  };
}

// 'all': every available backend that implements `method`; else the listed ids.
Result<std::vector<std::string>> ResolveBackends(client::SkinClient& client,
                                                 const std::string& wanted, SkinningMethod method) {
  auto list = client.ListBackends();
  if (!list.ok()) return list.status();
  std::vector<std::string> ids;
  if (wanted == "all") {
    for (const auto& b : list->backends()) {
      const bool has_method = std::find(b.methods().begin(), b.methods().end(),
                                        client::WireMethod(method)) != b.methods().end();
      if (b.available() && has_method) {
        ids.push_back(b.id());
      } else if (b.available()) {
        fmt::print(stderr, "note: skipping {}: no {} skinning\n", b.id(), MethodName(method));
      } else {
        fmt::print(stderr, "note: skipping {}: {}\n", b.id(), b.unavailable_reason());
      }
    }
    return ids;
  }
  std::stringstream stream(wanted);
  for (std::string id; std::getline(stream, id, ',');) ids.push_back(id);
  return ids;
}

Result<std::string> Upload(client::SkinClient& client, const Workload& w) {
  auto info = client.Upload(*w.arrays);
  if (!info.ok()) return info.status();
  return info->mesh_id();
}

// The glTF character when --mesh names one, else the synthetic mesh of this shape.
Result<Workload> LoadWorkload(const Options& o, uint32_t vertices, uint32_t bones, uint64_t seed) {
  const SkinningMethod method = *ParseMethod(o.method);
  if (!o.mesh.empty()) {
    auto workload = MakeGltfWorkload(o.mesh, o.primitive, o.normals);
    if (workload.ok()) workload->method = method;
    return workload;
  }
  return MakeWorkload(vertices, bones, o.joints, o.normals, seed, method);
}

int RunMain(const Options& o) {
  client::SkinClient client(client::MakeChannel(o.run.target));
  if (Status s = client::WaitUntilServing(client.channel(), std::chrono::seconds(10)); !s.ok()) {
    fmt::print(stderr, "error: {}: {}\n", o.run.target, s.ToString());
    return 1;
  }
  auto backends = ResolveBackends(client, o.backends, *ParseMethod(o.method));
  if (!backends.ok()) {
    fmt::print(stderr, "error: {}\n", backends.status().ToString());
    return 1;
  }
  std::vector<std::pair<uint32_t, uint32_t>> grid = {{o.vertices, o.bones}};
  if (o.sweep == "paper") {
    grid.clear();
    for (uint32_t v : {25'000u, 100'000u, 400'000u, 1'600'000u}) {
      for (uint32_t b = 1; b <= 4; ++b) grid.push_back({v, b});
    }
  } else if (!o.sweep.empty()) {
    fmt::print(stderr, "error: --sweep knows only 'paper'\n");
    return 2;
  }

  std::vector<RunResult> results;
  if (o.capacity) {
    // Open loop at the given rate; grow the stream count until p99 exceeds one frame or a
    // frame is dropped or fails, then bisect.
    auto loaded = LoadWorkload(o, o.vertices, o.bones, o.seed);
    if (!loaded.ok()) return fmt::print(stderr, "error: {}\n", loaded.status().ToString()), 1;
    const Workload& w = *loaded;
    auto mesh = Upload(client, w);
    if (!mesh.ok()) return fmt::print(stderr, "error: {}\n", mesh.status().ToString()), 1;
    const double budget_ms = 1000.0 / o.run.rate;
    const std::string backend = backends->empty() ? "" : backends->front();
    fmt::print(
        "capacity of {} at {:.0f} fps per stream, {} vertices x {} bones: p99 <= {:.1f} "
        "ms, nothing dropped\n{:>8} {:>9} {:>9} {:>9} {:>8} {:>8} {:>7}\n",
        backend, o.run.rate, w.vertices, w.bones, budget_ms, "streams", "frames/s", "p99 ms",
        "max ms", "late", "dropped", "holds");
    auto probe = [&](int streams) {
      RunConfig config = o.run;
      config.backend = backend;
      config.streams = streams;
      RunResult r = RunLoad(config, w, *mesh, MakeProgress(fmt::format("{} streams", streams)));
      const LatencySummary l = Summarize(r.latencies_ms);
      const bool holds = l.p99 <= budget_ms && r.dropped == 0 && !r.failed() && r.frames > 0;
      fmt::print("{:>8} {:>9.1f} {:>9.2f} {:>9.2f} {:>8} {:>8} {:>7}\n", streams,
                 r.frames_per_second(), l.p99, l.max, r.late, r.dropped, holds ? "yes" : "no");
      results.push_back(std::move(r));
      return holds;
    };
    int good = 0, bad = 0;
    for (int n = 1; n <= o.capacity_max_streams; n *= 2) {
      if (!probe(n)) {
        bad = n;
        break;
      }
      good = n;
    }
    while (bad > 0 && bad - good > 1) {
      const int mid = (good + bad) / 2;
      (probe(mid) ? good : bad) = mid;
    }
    fmt::print("capacity: {} concurrent {:.0f} fps streams ({}{})\n", good, o.run.rate, backend,
               bad == 0 ? fmt::format(", the most tried: {}", o.capacity_max_streams) : "");
  } else {
    for (const auto& [v, b] : grid) {
      auto loaded = LoadWorkload(o, v, b, o.seed + v + b);
      if (!loaded.ok()) return fmt::print(stderr, "error: {}\n", loaded.status().ToString()), 1;
      const Workload& w = *loaded;
      auto mesh = Upload(client, w);
      if (!mesh.ok()) return fmt::print(stderr, "error: {}\n", mesh.status().ToString()), 1;
      for (const std::string& backend : *backends) {
        RunConfig config = o.run;
        config.backend = backend;
        results.push_back(
            RunLoad(config, w, *mesh, MakeProgress(fmt::format("{} {}x{}", backend, v, b))));
      }
      // A sweep stores 16 meshes; free each when done with it.
      if (grid.size() > 1) (void)client.DeleteMesh(*mesh);
    }
    PrintTable(results, o.run.rate > 0);
    if (grid.size() > 1) PrintSpeedupTables(results);
  }

  int code = 0;
  for (const RunResult& r : results) {
    if (r.failed() && !o.capacity) code = 1;  // capacity probes past the limit may fail
    if (r.mismatches > 0) code = 1;
  }
  for (const auto& [path, write] : {std::pair{o.json, &WriteJson}, std::pair{o.csv, &WriteCsv},
                                    std::pair{o.plot, &WritePlot}}) {
    if (path.empty()) continue;
    if (Status s = write(path, results); !s.ok()) {
      fmt::print(stderr, "error: {}\n", s.ToString());
      code = 1;
    } else {
      fmt::print("wrote {}\n", path);
      if (write == &WritePlot && grid.size() > 1) fmt::print("wrote {}\n", SpeedupPlotPath(path));
    }
  }
  return code;
}

}  // namespace
}  // namespace skinserve::load

int main(int argc, char** argv) {
  using namespace skinserve::load;
  Options o;
  CLI::App app{
      "skinserve-load: throughput, latency and capacity of each backend through the "
      "real service"};
  app.add_option("--target", o.run.target,
                 "gRPC target; several servers: ipv4:127.0.0.1:50051,127.0.0.1:50052 "
                 "(round_robin)")
      ->envname("SKINSERVE_TARGET")
      ->capture_default_str();
  app.add_option("--backends", o.backends, "comma-separated ids, or 'all' (as the server lists)")
      ->capture_default_str();
  app.add_option("--vertices", o.vertices, "synthetic mesh: vertices")->capture_default_str();
  app.add_option("--bones", o.bones, "synthetic mesh: influences per vertex")
      ->capture_default_str();
  app.add_option("--joints", o.joints, "synthetic mesh: joints")->capture_default_str();
  app.add_flag("--normals", o.normals, "skin normals too");
  app.add_option("--method", o.method,
                 "skinning method: linear, or dual-quaternion (synthetic palettes are then "
                 "rigid; 'all' backends means those that implement it)")
      ->check(CLI::IsMember({"linear", "dual-quaternion"}))
      ->capture_default_str();
  app.add_option("--seed", o.seed, "synthetic mesh and palettes seed")->capture_default_str();
  app.add_option("--streams", o.run.streams, "concurrent streams")->capture_default_str();
  app.add_option("--window", o.run.window, "frames in flight per stream")->capture_default_str();
  app.add_option("--duration", o.run.duration_seconds, "measured seconds per run")
      ->capture_default_str();
  app.add_option("--frames", o.run.frames,
                 "measure this many frames per stream (after the warm-up) instead of --duration")
      ->excludes("--duration");
  app.add_option("--warmup", o.run.warmup_seconds, "seconds before measuring")
      ->capture_default_str();
  app.add_option("--rate", o.run.rate,
                 "open loop: frames/s per stream, sent on schedule (0: closed loop)")
      ->capture_default_str();
  app.add_option("--check-every", o.run.check_every,
                 "compare every Nth answer with a local float64 reference (0: never)")
      ->capture_default_str();
  app.add_option("--sweep", o.sweep, "'paper': 25k..1600k vertices x 1..4 bones, every backend");
  app.add_option("--mesh", o.mesh,
                 "a glTF 2.0 character (.glb/.gltf) as the mesh; palettes sample its first clip, "
                 "a new time each frame")
      ->excludes("--vertices", "--bones", "--joints", "--sweep");
  app.add_option("--primitive", o.primitive, "--mesh: which skinned primitive")
      ->capture_default_str();
  app.add_flag("--capacity", o.capacity,
               "find the most concurrent --rate streams (default 60 fps) held with p99 within "
               "one frame and nothing dropped, on the first --backends entry");
  app.add_option("--capacity-max-streams", o.capacity_max_streams, "upper end of the search")
      ->capture_default_str();
  app.add_option("--json", o.json, "write results as JSON");
  app.add_option("--csv", o.csv, "write results as CSV");
  app.add_option("--plot", o.plot, "write a PNG chart (gnuplot)");
  CLI11_PARSE(app, argc, argv);
  if (o.capacity) {
    if (o.run.rate <= 0) o.run.rate = 60;
    if (app.count("--vertices") == 0) o.vertices = 25'000;
    if (o.backends == "all") o.backends = "sse-openmp";
  }
  return RunMain(o);
}
