// skinserve-load: what each backend delivers through the real service.
//   closed loop   --streams N --window W --duration S (or --frames N per stream)
//   open loop     --rate FPS (per stream), late and dropped frames reported; --rate-range
//                 START:END:STEP one row per rate; --arrivals constant|poisson
//   --sweep paper the paper's grid over every backend, tables 2 and 3 layout
//   --characters-per-tick N  each request a tick of N characters, N distinct meshes
//   --animate synthetic|FILE.glb  frames carry a pose of a clip uploaded once, posed on the
//                 server (the synthetic rig, or a glTF character's skeleton and --clip)
//   --capacity    the most characters (streams x N a tick x --instances) held at 60 fps with
//                 the latency at --percentile (p99) within one frame and nothing dropped, per
//                 --modes (encoding x crowd size)
#include <fmt/format.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <optional>
#include <sstream>

#include "connection_flags.h"
#include "gltf_pose_workload.h"
#include "load_report.h"
#include "load_runner.h"
#include "measurement_flags.h"
#include "pose_workload.h"
#include "skinserve/cli/config_file.h"
#include "skinserve/cli/version.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/malloc_tuning.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/encoding/vertex_encoding.h"

namespace skinserve::load {
namespace {

struct Options {
  RunConfig run;
  client::ConnectionFlags connection;  // TLS and keepalive
  double deadline_seconds = 30, stream_idle_seconds = 30;
  std::string backends = "all";
  uint32_t vertices = 100'000, bones = 2, joints = 77;
  bool normals = false;
  bool tangents = false;  // tangents asked for back and checked (needs --normals)
  std::string method = "linear";
  uint64_t seed = 1;
  MorphWorkload morph;      // synthetic mesh: morph targets and active weights per frame
  std::string mesh;         // a glTF file instead of the synthetic mesh
  int primitive = -1;       // --mesh: -1 is the whole character
  std::string animate;      // "synthetic" or a .glb: poses of its clip instead of palettes
  std::string clip;         // --animate FILE: the clip's name or index (empty: the first)
  float clip_error_mm = 0;  // --clip-error-mm: UploadClipRequest.max_error_mm
  std::string sweep;
  bool capacity = false;
  int capacity_max_streams = 64;
  std::string encoding = "float32";
  std::string rest_encoding;         // how the server stores the mesh; empty: not asked
  std::string modes;                 // --capacity: ENCODING[xK] list, e.g. float32,snorm16x16
  std::string data_planes = "grpc";  // grpc, shm and/or socket, each run once per data plane
  std::string frame_socket;          // the socket plane's: the server's --frame-socket
  std::string json, csv, plot;
  MeasurementFlags measurement;  // rates, arrivals, percentile, stability, server metrics
};

// An answer encoding and a crowd batch size: "snorm16x16" is snorm16 with 16 instances.
struct Mode {
  VertexEncoding encoding = VertexEncoding::kFloat32;
  uint32_t instances = 1;
  std::string Name() const {
    return instances > 1 ? fmt::format("{}x{}", VertexEncodingName(encoding), instances)
                         : VertexEncodingName(encoding);
  }
};

Result<Mode> ParseMode(const std::string& text) {
  const std::size_t x = text.find('x');
  const auto encoding = ParseVertexEncoding(text.substr(0, x));
  Mode mode;
  if (!encoding) {
    return InvalidArgument(fmt::format(
        "mode '{}': the encoding must be float32, float16 or snorm16 (then xK: K instances)",
        text));
  }
  mode.encoding = *encoding;
  if (x != std::string::npos) {
    const std::string k = text.substr(x + 1);
    if (k.empty() || k.size() > 6 || k.find_first_not_of("0123456789") != std::string::npos ||
        std::stoul(k) == 0) {
      return InvalidArgument(
          fmt::format("mode '{}': K after 'x' must be a whole number >= 1", text));
    }
    mode.instances = static_cast<uint32_t>(std::stoul(k));
  }
  return mode;
}

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

std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream stream(text);
  for (std::string item; std::getline(stream, item, ',');) {
    if (!item.empty()) items.push_back(item);
  }
  return items;
}

// 'all': every available backend that implements `method` (and morph targets, when the
// frames carry morph weights); else the listed ids.
// `config` set for data plane `plane`: grpc (vertices in the answers), shm (into each
// stream's region, requests on StreamSkin) or socket (into the region, requests on the
// server's frame socket).
void UsePlane(const std::string& plane, const Options& o, RunConfig* config) {
  config->shared_memory = plane != "grpc";
  config->frame_socket = plane == "socket" ? o.frame_socket : std::string();
}

// A mode's label in the capacity lines: "+shm" or "+socket" after it for those planes.
std::string PlaneLabel(const std::string& mode, const std::string& plane) {
  return plane == "grpc" ? mode : mode + "+" + plane;
}

Result<std::vector<std::string>> ResolveBackends(client::SkinClient& client,
                                                 const std::string& wanted, SkinningMethod method,
                                                 bool morph) {
  auto list = client.ListBackends();
  if (!list.ok()) return list.status();
  std::vector<std::string> ids;
  if (wanted == "all") {
    for (const auto& b : list->backends()) {
      const bool has_method = std::find(b.methods().begin(), b.methods().end(),
                                        wire::ToWire(method)) != b.methods().end();
      if (b.available() && has_method && (!morph || b.morph_targets())) {
        ids.push_back(b.id());
      } else if (b.available() && has_method) {
        fmt::print(stderr, "note: skipping {}: no morph targets\n", b.id());
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
  auto info = client.Upload(*w.arrays, {.rest_encoding = w.rest_encoding});
  if (!info.ok()) return info.status();
  return info->mesh_id();
}

// A run's meshes, uploaded: one, or with ticks one per character (UploadedMesh points into
// `workloads`, which is never resized after).
struct RunMeshes {
  std::vector<Workload> workloads;
  std::vector<UploadedMesh> meshes;
};

// --animate FILE: the glTF character whose clip the frames play (not 'synthetic').
bool AnimatesFile(const Options& o) { return !o.animate.empty() && o.animate != "synthetic"; }

// The glTF file that is the mesh: --mesh, or --animate FILE; empty: the synthetic mesh.
std::string CharacterFile(const Options& o) { return AnimatesFile(o) ? o.animate : o.mesh; }

// --animate: the synthetic rig of the synthetic mesh, or the file's skeleton and --clip.
// The file's is checked against its float64 values: the mesh must be stored as float32.
Status AddPose(const Options& o, uint64_t seed, Workload* w) {
  if (!AnimatesFile(o)) {
    w->pose = MakePoseWorkload(o.joints, seed);
    w->pose->max_error_mm = o.clip_error_mm;
    return Status::Ok();
  }
  auto pose = MakeGltfPoseWorkload(o.animate, o.clip);
  if (!pose.ok()) return pose.status();
  w->pose = *std::move(pose);
  w->pose->max_error_mm = o.clip_error_mm;
  if (w->rest_encoding != RestEncoding::kFloat32) {
    return InvalidArgument(fmt::format(
        "--animate {}: the check compares with the file's float64 values, so the mesh is "
        "stored float32; not {} ({})",
        o.animate, RestEncodingName(w->rest_encoding), w->rest_encoding_reason));
  }
  return Status::Ok();
}

// The glTF character of CharacterFile when there is one, else the synthetic mesh of this
// shape; with --animate its pose.
Result<Workload> LoadWorkload(const Options& o, uint32_t vertices, uint32_t bones, uint64_t seed) {
  const SkinningMethod method = *ParseMethod(o.method);
  if (o.tangents && !o.normals) return InvalidArgument("--tangents needs --normals");
  const std::string file = CharacterFile(o);
  Result<Workload> workload =
      file.empty() ? Result<Workload>(MakeWorkload(vertices, bones, o.joints, o.normals, seed,
                                                   method, o.morph, o.tangents))
                   : MakeGltfWorkload(file, o.primitive, o.normals, o.tangents);
  if (!workload.ok()) return workload;
  workload->method = method;
  const std::optional<RestEncoding> asked =
      o.rest_encoding.empty() ? std::nullopt : ParseRestEncoding(o.rest_encoding);
  if (Status s = ChooseRestEncoding(&*workload, asked); !s.ok()) return s;
  if (!o.animate.empty()) {
    if (Status s = AddPose(o, seed, &*workload); !s.ok()) return s;
  }
  return workload;
}

// The workload of `seed` (LoadWorkload), or with ticks of N characters N distinct synthetic
// meshes of this shape, character c's seeded seed + c, each uploaded once (with --animate
// its skeleton and clip too). --animate FILE: every character of a tick is the file's, its
// mesh, skeleton and clip uploaded once.
Result<std::unique_ptr<RunMeshes>> LoadAndUpload(client::SkinClient& client, const Options& o,
                                                 uint32_t vertices, uint32_t bones, uint64_t seed) {
  auto run = std::make_unique<RunMeshes>();
  const uint32_t characters = std::max(o.run.characters_per_tick, 1u);
  const bool one_character = AnimatesFile(o);
  for (uint32_t c = 0; c < characters; ++c) {
    if (one_character && c > 0) {
      run->workloads.push_back(run->workloads.front());  // shares its pose (and ids)
      continue;
    }
    auto loaded = LoadWorkload(o, vertices, bones, seed + c);
    if (!loaded.ok()) return loaded.status();
    run->workloads.push_back(std::move(loaded).value());
  }
  for (Workload& w : run->workloads) {
    if (one_character && !run->meshes.empty()) {
      run->meshes.push_back({&w, run->meshes.front().mesh_id});
      continue;
    }
    auto mesh = Upload(client, w);
    if (!mesh.ok()) return mesh.status();
    if (w.pose) {
      const bool first = run->meshes.empty();
      if (Status s = UploadPose(client, w.pose.get(), first); !s.ok()) return s;
    }
    run->meshes.push_back({&w, *mesh});
  }
  return run;
}

bool Serving(client::SkinClient& client, const std::string& target) {
  if (Status s = client::WaitUntilServing(client.channel(), std::chrono::seconds(10)); !s.ok()) {
    fmt::print(stderr, "error: {}: {}\n", target, s.ToString());
    if (const std::string hint = client::ConnectionHint(s); !hint.empty()) {
      fmt::print(stderr, "hint: {}\n", hint);
    }
    return false;
  }
  return true;
}

// Whether frames carry morph weights: a glTF character's are known once it is loaded (its
// rest encoding is told then too).
Result<bool> FramesCarryMorph(const Options& o) {
  if (CharacterFile(o).empty()) return o.morph.targets > 0 && o.morph.active > 0;
  auto probe = LoadWorkload(o, o.vertices, o.bones, o.seed);
  if (!probe.ok()) return probe.status();
  fmt::print(stderr, "note: rest encoding {} for {}: {}\n", RestEncodingName(probe->rest_encoding),
             CharacterFile(o), probe->rest_encoding_reason);
  return std::any_of(probe->morph_weights.begin(), probe->morph_weights.end(),
                     [](const std::vector<MorphWeight>& w) { return HasActiveMorph(w); });
}

using Grid = std::vector<std::pair<uint32_t, uint32_t>>;  // vertices x bones

// The mesh shapes to run: the one asked for, or --sweep paper's 16.
Result<Grid> SweepGrid(const Options& o) {
  Grid grid = {{o.vertices, o.bones}};
  if (o.sweep == "paper") {
    grid.clear();
    for (uint32_t v : {25'000u, 100'000u, 400'000u, 1'600'000u}) {
      for (uint32_t b = 1; b <= 4; ++b) grid.push_back({v, b});
    }
  } else if (!o.sweep.empty()) {
    return InvalidArgument("--sweep knows only 'paper'");
  }
  return grid;
}

// --rate, or each rate of --rate-range.
Result<std::vector<double>> Rates(const Options& o) {
  if (o.measurement.rate_range.empty()) return std::vector<double>{o.run.rate};
  return ParseRateRange(o.measurement.rate_range);
}

int MeasureFailed(const Status& s) {
  fmt::print(stderr, "error: {}\n", s.ToString());
  return 1;
}

// What every capacity search of a run shares: the meshes, the backend and the bound held.
struct CapacityPlan {
  const Options& o;
  const Workload& w;
  const std::vector<UploadedMesh>& meshes;
  std::string backend;
  MeasureOptions measure;
  int per_tick;      // characters a tick (1 without ticks)
  double budget_ms;  // the latency bound at the percentile
  std::string at;    // the percentile's name, "p99"
  bool cpu;          // the server CPU columns
  bool ticks() const { return o.run.characters_per_tick > 0; }
};

void PrintCapacityHeader(const CapacityPlan& p, const Mode& mode, const std::string& plane) {
  fmt::print(
      "capacity of {} at {:.0f} {} per stream, {} vertices x {} bones, {}, {}{} instance(s) "
      "per {}, {} data plane: {} <= {:.1f} ms, nothing dropped\n{:>8} {:>10} {:>9} "
      "{:>9} {:>9} {:>8} {:>8} {:>7}{}\n",
      p.backend, p.o.run.rate, p.ticks() ? "ticks/s" : "fps", p.w.vertices, p.w.bones,
      VertexEncodingName(mode.encoding),
      p.ticks() ? fmt::format("ticks of {} characters (distinct meshes), ", p.per_tick) : "",
      mode.instances, p.ticks() ? "character" : "stream", plane, p.at, p.budget_ms, "streams",
      "characters", p.ticks() ? "ticks/s" : "frames/s", p.at + " ms", "max ms", "late", "dropped",
      "holds", p.cpu ? ServerCpuHeader() : "");
}

// One probe of a capacity search: `streams` streams of `mode` over `plane`, its row printed
// and kept; whether the bound held.
Result<bool> ProbeCapacity(const CapacityPlan& p, const Mode& mode, const std::string& plane,
                           int streams, std::vector<RunResult>* results) {
  RunConfig config = p.o.run;
  config.backend = p.backend;
  config.streams = streams;
  config.encoding = mode.encoding;
  config.instances = mode.instances;
  UsePlane(plane, p.o, &config);
  const std::string label = PlaneLabel(mode.Name(), plane);
  auto measured = Measure(config, p.meshes,
                          MakeProgress(fmt::format("{} {} streams", label, streams)), p.measure);
  if (!measured.ok()) return measured.status();
  RunResult r = std::move(measured).value();
  const LatencySummary l = Summarize(r.latencies_ms, r.percentile);
  const bool holds = r.within_limit() && r.dropped == 0 && !r.failed() && r.frames > 0;
  fmt::print("{:>8} {:>10} {:>9.1f} {:>9.2f} {:>9.2f} {:>8} {:>8} {:>7}{}\n", streams,
             streams * p.per_tick * static_cast<int>(mode.instances), r.frames_per_second(),
             l.at_percentile, l.max, r.late, r.dropped, holds ? "yes" : "no",
             p.cpu ? ServerCpuCells(r) : "");
  // A probe that failed on errors says which, so the search's end is not read as a speed.
  for (const auto& [code, message] : r.error_examples) {
    fmt::print("         errors: {} x{}, the first: {}\n", code, r.errors.at(code), message);
  }
  results->push_back(std::move(r));
  return holds;
}

// Grows the stream count (doubling up to --capacity-max-streams) until the bound breaks,
// then bisects: {the most streams that held, the fewest that did not (0: none)}.
Result<std::pair<int, int>> SearchCapacity(const CapacityPlan& p, const Mode& mode,
                                           const std::string& plane,
                                           std::vector<RunResult>* results) {
  int good = 0, bad = 0;
  for (int n = 1; n <= p.o.capacity_max_streams; n *= 2) {
    const Result<bool> holds = ProbeCapacity(p, mode, plane, n, results);
    if (!holds.ok()) return holds.status();
    if (!*holds) {
      bad = n;
      break;
    }
    good = n;
  }
  while (bad > 0 && bad - good > 1) {
    const int mid = (good + bad) / 2;
    const Result<bool> holds = ProbeCapacity(p, mode, plane, mid, results);
    if (!holds.ok()) return holds.status();
    (*holds ? good : bad) = mid;
  }
  return std::pair{good, bad};
}

// --capacity: open loop at the given rate, per mode and data plane; grow the stream count
// until the percentile exceeds one frame or a frame is dropped or fails, then bisect.
// Characters = streams x instances (x N with ticks of N).
int RunCapacity(client::SkinClient& client, const Options& o,
                const std::vector<std::string>& backends, MeasureOptions measure,
                std::vector<RunResult>* results) {
  auto loaded = LoadAndUpload(client, o, o.vertices, o.bones, o.seed);
  if (!loaded.ok()) return fmt::print(stderr, "error: {}\n", loaded.status().ToString()), 1;
  std::vector<Mode> modes;
  for (const std::string& text : SplitList(o.modes)) {
    auto mode = ParseMode(text);
    if (!mode.ok()) return fmt::print(stderr, "error: --modes: {}\n", mode.status().message()), 2;
    modes.push_back(*mode);
  }
  if (modes.empty()) modes.push_back({*ParseVertexEncoding(o.encoding), o.run.instances});
  measure.latency_limit_ms = measure.latency_limit_ms.value_or(1000.0 / o.run.rate);
  const CapacityPlan p{.o = o,
                       .w = (*loaded)->workloads.front(),
                       .meshes = (*loaded)->meshes,
                       .backend = backends.empty() ? "" : backends.front(),
                       .measure = measure,
                       .per_tick = static_cast<int>(std::max(o.run.characters_per_tick, 1u)),
                       .budget_ms = *measure.latency_limit_ms,
                       .at = fmt::format("p{:g}", measure.percentile),
                       .cpu = !measure.metrics_url.empty()};
  std::vector<std::pair<std::string, int>> held;  // characters per mode and data plane
  for (const Mode& mode : modes) {
    for (const std::string& plane : SplitList(o.data_planes)) {
      const std::string label = PlaneLabel(mode.Name(), plane);
      PrintCapacityHeader(p, mode, plane);
      const auto found = SearchCapacity(p, mode, plane, results);
      if (!found.ok()) return MeasureFailed(found.status());
      const auto [good, bad] = *found;
      const int characters = good * p.per_tick * static_cast<int>(mode.instances);
      fmt::print(
          "capacity: {} characters ({} streams x {}{} instances, {:.0f} {}, {}, {}{})\n",
          characters, good, p.ticks() ? fmt::format("{} characters a tick x ", p.per_tick) : "",
          mode.instances, o.run.rate, p.ticks() ? "ticks/s" : "fps", p.backend, label,
          bad == 0 ? fmt::format(", the most streams tried: {}", o.capacity_max_streams) : "");
      held.push_back({label, characters});
    }
  }
  if (held.size() > 1) {
    fmt::print("\ncharacters held at {:.0f} {} ({} <= {:.1f} ms, nothing dropped), {}:\n",
               o.run.rate, p.ticks() ? "ticks/s" : "fps", p.at, p.budget_ms, p.backend);
    for (const auto& [label, characters] : held) fmt::print("  {:<18} {:>6}\n", label, characters);
  }
  return 0;
}

// One row per mesh shape, backend, data plane and rate; then the tables.
int RunGrid(client::SkinClient& client, const Options& o, const std::vector<std::string>& backends,
            const Grid& grid, const std::vector<double>& rates, const MeasureOptions& measure,
            std::vector<RunResult>* results) {
  for (const auto& [v, b] : grid) {
    auto loaded = LoadAndUpload(client, o, v, b, o.seed + v + b);
    if (!loaded.ok()) return fmt::print(stderr, "error: {}\n", loaded.status().ToString()), 1;
    const std::vector<UploadedMesh>& meshes = (*loaded)->meshes;
    for (const std::string& backend : backends) {
      for (const std::string& plane : SplitList(o.data_planes)) {
        for (const double rate : rates) {
          RunConfig config = o.run;
          config.backend = backend;
          UsePlane(plane, o, &config);
          config.rate = rate;
          auto row =
              Measure(config, meshes,
                      MakeProgress(fmt::format("{} {} {}x{}{}", backend, plane, v, b,
                                               rate > 0 ? fmt::format(" {:g}/s", rate) : "")),
                      measure);
          if (!row.ok()) return MeasureFailed(row.status());
          results->push_back(std::move(row).value());
          // perf_analyzer's --latency-threshold: higher rates would only be further over.
          if (rates.size() > 1 && !results->back().within_limit()) break;
        }
      }
    }
    // A sweep stores 16 meshes; free each when done with it.
    if (grid.size() > 1) {
      for (const UploadedMesh& m : meshes) (void)client.DeleteMesh(m.mesh_id);
    }
  }
  PrintTable(*results, rates.front() > 0);
  if (grid.size() > 1) PrintSpeedupTables(*results);
  return 0;
}

// The exit status the rows give (1 on a failed row or a mismatch), and the report files.
int WriteReports(const Options& o, const std::vector<RunResult>& results, bool sweep) {
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
      if (write == &WritePlot && sweep) fmt::print("wrote {}\n", SpeedupPlotPath(path));
    }
  }
  return code;
}

int RunMain(const Options& o) {
  client::SkinClient client(client::MakeChannel(o.run.target, o.run.channel), o.run.limits);
  if (!Serving(client, o.run.target)) return 1;
  const Result<bool> morph = FramesCarryMorph(o);
  if (!morph.ok()) return fmt::print(stderr, "error: {}\n", morph.status().ToString()), 1;
  auto backends = ResolveBackends(client, o.backends, *ParseMethod(o.method), *morph);
  if (!backends.ok()) {
    fmt::print(stderr, "error: {}\n", backends.status().ToString());
    return 1;
  }
  const Result<Grid> grid = SweepGrid(o);
  if (!grid.ok()) return fmt::print(stderr, "error: {}\n", grid.status().message()), 2;
  const Result<std::vector<double>> rates = Rates(o);
  if (!rates.ok()) return fmt::print(stderr, "error: {}\n", rates.status().message()), 2;
  MeasureOptions measure = o.measurement.measure;
  if (o.measurement.latency_limit_ms > 0) measure.latency_limit_ms = o.measurement.latency_limit_ms;
  std::vector<RunResult> results;
  const int failed = o.capacity ? RunCapacity(client, o, *backends, measure, &results)
                                : RunGrid(client, o, *backends, *grid, *rates, measure, &results);
  if (failed != 0) return failed;
  return WriteReports(o, results, grid->size() > 1);
}

// Where the server is and how long calls may take.
void AddConnectionOptions(CLI::App& app, Options& o) {
  app.add_option("--target", o.run.target,
                 "gRPC target; several servers: ipv4:127.0.0.1:50051,127.0.0.1:50052 "
                 "(round_robin)")
      ->envname("SKINSERVE_TARGET")
      ->capture_default_str();
  client::AddConnectionFlags(app, o.connection);
  app.add_option("--deadline-seconds", o.deadline_seconds,
                 "deadline of each unary call (uploads: 300 s) (0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--stream-idle-seconds", o.stream_idle_seconds,
                 "a stream with frames in flight and no answer for this long is ended, its "
                 "frames failed DEADLINE_EXCEEDED (0: wait for ever)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

// The backends and the mesh they skin: its shape, normals, tangents, method, morph targets.
void AddMeshOptions(CLI::App& app, Options& o) {
  app.add_option("--backends", o.backends, "comma-separated ids, or 'all' (as the server lists)")
      ->capture_default_str();
  app.add_option("--vertices", o.vertices, "synthetic mesh: vertices")->capture_default_str();
  app.add_option("--bones", o.bones, "synthetic mesh: influences per vertex")
      ->capture_default_str();
  app.add_option("--joints", o.joints, "synthetic mesh: joints")->capture_default_str();
  app.add_flag("--normals", o.normals, "skin normals too");
  app.add_flag("--tangents", o.tangents,
               "skin tangents too and check them against the float64 reference (the synthetic "
               "mesh gets tangents; a --mesh character must have them in every primitive); "
               "needs --normals and backends whose BackendInfo.tangents is set");
  app.add_option("--method", o.method,
                 "skinning method: linear, or dual-quaternion (synthetic palettes are then "
                 "rigid; 'all' backends means those that implement it)")
      ->check(CLI::IsMember({"linear", "dual-quaternion"}))
      ->capture_default_str();
  app.add_option("--morph-targets", o.morph.targets,
                 "synthetic mesh: this many random morph targets (0: none)")
      ->check(CLI::Range(0u, kMaxMorphTargets))
      ->capture_default_str();
  app.add_option("--morph-coverage", o.morph.coverage,
                 "--morph-targets: the fraction of the vertices each target moves")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--morph-active", o.morph.active,
                 "--morph-targets: targets with a non-zero weight per frame (random weights in "
                 "[-1.5, 1.5]; 0: frames carry none); crowd instances each get their own")
      ->capture_default_str();
  app.add_option("--seed", o.seed,
                 "synthetic mesh and palettes seed; Poisson arrivals' and --animate's rig too")
      ->capture_default_str();
  app.add_option("--animate", o.animate,
                 "'synthetic': the synthetic mesh gets a synthetic skeleton of --joints joints "
                 "and a 2 s clip (seeded --seed); FILE.glb: the mesh is that glTF character (one "
                 "skinned primitive) with its skeleton and --clip. Uploaded once; each frame then "
                 "carries a pose (the clip at its frame's time at 30 fps, looped) instead of a "
                 "palette, posed on the server, and --check-every compares with the clip "
                 "evaluated in float64 (a file: its original channels and primitive, read apart "
                 "from the importer); rows '+pose' ('+pose:CLIP' for a file); one instance a "
                 "character, linear skinning");
  app.add_option("--clip", o.clip,
                 "--animate FILE: the clip to play, by name or index (default: the file's first)");
  app.add_option("--clip-error-mm", o.clip_error_mm,
                 "--animate: the error the server stores the clip to, in mm (every joint within "
                 "it + 1e-4 of its distance from the origin; 0: the server's default, 0.01 mm; "
                 "else 0.01 to 10, checked by the server): looser stores fewer bytes; "
                 "--check-every's bound grows by it over 0.01 mm")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
}

// How each run drives the server: streams, window, duration or frames, rate, checks, encodings,
// ticks and crowds.
void AddRunOptions(CLI::App& app, Options& o) {
  app.add_option("--streams", o.run.streams, "concurrent streams")->capture_default_str();
  app.add_option("--window", o.run.window, "frames in flight per stream")->capture_default_str();
  app.add_option("--streams-per-connection", o.run.streams_per_connection,
                 "streams sharing one TCP connection; more streams open more connections "
                 "(the server takes --max-streams-per-connection on one, default 128)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
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
  app.add_option("--encoding", o.encoding,
                 "answers in float32 (as computed), float16 or snorm16 (quantized to each "
                 "instance's box); checks allow the encoding's stated error")
      ->check(CLI::IsMember({"float32", "float16", "snorm16"}))
      ->capture_default_str();
  app.add_option(
         "--rest-encoding", o.rest_encoding,
         "how the server stores the mesh: float32, or quantized16 / quantized8-weights "
         "(16-bit positions, normals and weights, or 8-bit weights; read directly by "
         "simd, simd-openmp and the OpenCL backends); checks compare with the values it "
         "decodes to. Default: float32, but a --mesh file storing 8- or 16-bit positions and "
         "integer weights (KHR_mesh_quantization) gets quantized16 (quantized8-weights "
         "for UNSIGNED_BYTE weights); the choice and why is printed")
      ->check(CLI::IsMember({"float32", "quantized16", "quantized8-weights"}));
  app.add_option("--characters-per-tick", o.run.characters_per_tick,
                 "ticks: each request carries N characters, N distinct synthetic meshes of "
                 "--vertices/--bones/--joints (character c seeded --seed + c, each uploaded "
                 "once), each with its own palettes (--instances: a crowd each) and morph "
                 "weights; frames, latency and --rate count ticks, characters/s and "
                 "--capacity count characters (0: plain frames)")
      ->check(CLI::Range(0u, 4096u))
      ->capture_default_str();
  app.add_option("--instances", o.run.instances,
                 "crowd batches: K palettes per request, K characters per stream")
      ->check(CLI::Range(1u, 1u << 16))
      ->capture_default_str();
}

// What is searched or swept (--capacity, --sweep, --modes, --mesh) and over which data planes.
void AddSearchOptions(CLI::App& app, Options& o) {
  app.add_option("--modes", o.modes,
                 "--capacity: one search per mode, ENCODING[xK] comma-separated, e.g. "
                 "float32,snorm16x16 (default: --encoding with --instances)");
  app.add_option("--sweep", o.sweep, "'paper': 25k..1600k vertices x 1..4 bones, every backend");
  app.add_option("--mesh", o.mesh,
                 "a glTF 2.0 character (.glb/.gltf) as the mesh; palettes (and morph target "
                 "weights) sample its first clip, a new time each frame")
      ->excludes("--vertices", "--bones", "--joints", "--sweep", "--morph-targets");
  app.add_option("--primitive", o.primitive,
                 "--mesh: only this primitive, skinned or rigid (default: the whole character)");
  app.add_flag("--capacity", o.capacity,
               "find the most concurrent --rate streams (default 60 fps) held with the latency at "
               "--percentile within one frame (or --latency-limit-ms) and nothing dropped, on the "
               "first --backends entry (default: "
               "simd-openmp, the fastest CPU loop on every CPU)");
  app.add_option("--capacity-max-streams", o.capacity_max_streams, "upper end of the search")
      ->capture_default_str();
  app.add_option("--data-planes", o.data_planes,
                 "how frames travel, each run once per entry, comma-separated: grpc (the "
                 "vertices in the gRPC answers), shm (written into a shared-memory region of "
                 "each stream's: the server must run on this host, with --shm-dir as here) and "
                 "socket (as shm, the requests and answers over the server's --frame-socket "
                 "instead of gRPC: needs --frame-socket; without --rate a closed loop for "
                 "--duration)")
      ->check([](const std::string& text) {
        for (const std::string& plane : SplitList(text)) {
          if (plane != "grpc" && plane != "shm" && plane != "socket")
            return "grpc, shm, socket or a list of them: not '" + plane + "'";
        }
        return std::string();
      })
      ->capture_default_str();
  app.add_flag("--early-parts", o.run.early_parts,
               "crowds over gRPC: ask for each part as soon as its instances are skinned "
               "(compute and transport overlap) instead of after the frame's last instance");
  app.add_flag_callback(
      "--shared-memory", [&o] { o.data_planes = "shm"; },
      "the same-host shared-memory data plane alone (--data-planes shm)");
  app.add_option("--frame-socket", o.frame_socket,
                 "the socket data plane: the path of the server's --frame-socket");
  app.add_option("--shm-dir", o.run.shm_dir,
                 "where the streams' regions are made: the server's --shm-dir")
      ->capture_default_str();
}

// Why --animate FILE cannot go with the options given (empty: it can): the file is the
// mesh, whole, and the check skins positions and normals.
std::string AnimateFileRefusal(const CLI::App& app, const std::string& file) {
  if (!IsGlbPath(file)) {
    return "'synthetic' or a binary glTF file (.glb, which the float64 check reads)";
  }
  for (const char* option : {"--vertices", "--bones", "--joints", "--sweep", "--primitive"}) {
    if (app.count(option) > 0) {
      return fmt::format("the file is the mesh, the whole character: not with {}", option);
    }
  }
  if (app.count("--tangents") > 0) {
    return "the float64 check of a file skins positions and normals: not with --tangents";
  }
  return {};
}

// Why --animate cannot go with the other options (empty: it can): a pose is one
// character's, skinned linearly (the clip scales a joint: not rigid), of the synthetic mesh
// or the file's.
std::string AnimateRefusal(const CLI::App& app, const Options& o) {
  if (!o.mesh.empty()) {
    return o.animate == "synthetic"
               ? "poses the synthetic mesh: not with --mesh"
               : "the file is the mesh: not with --mesh (give the character to --animate only)";
  }
  if (o.animate != "synthetic") {
    if (std::string why = AnimateFileRefusal(app, o.animate); !why.empty()) return why;
  }
  if (o.run.instances > 1) return "a pose is one character's: not with --instances > 1";
  if (o.method != "linear") return "the clip scales a joint: not with --method dual-quaternion";
  // The server would apply the clip's weights track (4 weights) to the mesh's targets.
  if (o.morph.targets > 0)
    return "the server morphs the mesh by the clip's weights track: not with --morph-targets";
  return {};
}

// Completes `o` after parsing (encodings, arrivals, the channel, the limits, --capacity's
// defaults); an exit status when the options do not go together.
std::optional<int> FinishOptions(const CLI::App& app, Options& o) {
  o.run.encoding = *ParseVertexEncoding(o.encoding);
  o.run.arrivals = *ParseArrivals(o.measurement.arrivals);
  o.run.arrivals_seed = o.seed;
  if (o.run.frames > 0 && o.measurement.measure.max_trials > 1) {
    fmt::print(stderr, "error: --max-trials repeats windows of --duration: not with --frames\n");
    return 2;
  }
  const bool socket_plane = o.data_planes.find("socket") != std::string::npos;
  if (socket_plane && o.frame_socket.empty()) {
    fmt::print(stderr, "error: --data-planes socket: needs --frame-socket PATH (the server's)\n");
    return 2;
  }
  if (socket_plane && o.run.rate <= 0 && !o.capacity && o.run.frames > 0) {
    fmt::print(stderr,
               "error: --data-planes socket without --rate runs a closed loop for --duration: "
               "not with --frames\n");
    return 2;
  }
  if (o.run.characters_per_tick > 0 && !o.mesh.empty()) {
    fmt::print(stderr,
               "error: --characters-per-tick skins distinct synthetic meshes: not with --mesh\n");
    return 2;
  }
  if (!o.animate.empty()) {
    if (const std::string why = AnimateRefusal(app, o); !why.empty()) {
      fmt::print(stderr, "error: --animate {}: {}\n", o.animate, why);
      return 2;
    }
  }
  if (!o.clip.empty() && !AnimatesFile(o)) {
    fmt::print(stderr, "error: --clip picks the clip of --animate FILE.glb: not without it\n");
    return 2;
  }
  if (o.run.characters_per_tick > 0 && o.run.early_parts) {
    fmt::print(stderr,
               "error: --early-parts: a tick's characters come as they finish anyway: not with "
               "--characters-per-tick\n");
    return 2;
  }
  auto channel = o.connection.ToChannelOptions();
  if (!channel.ok()) {
    fmt::print(stderr, "error: {}\n", channel.status().ToString());
    return 2;
  }
  o.run.channel = *channel;
  o.run.limits.deadline = client::FlagMilliseconds(o.deadline_seconds);
  o.run.limits.stream_idle = client::FlagMilliseconds(o.stream_idle_seconds);
  if (o.capacity) {
    if (o.run.rate <= 0) o.run.rate = 60;
    if (app.count("--vertices") == 0) o.vertices = 25'000;
    // The fastest CPU loop, on every CPU (sse-openmp is x86 only): what an operator serves.
    if (o.backends == "all") o.backends = "simd-openmp";
  }
  return std::nullopt;
}

}  // namespace
}  // namespace skinserve::load

int main(int argc, char** argv) {
  using namespace skinserve::load;
  Options o;
  CLI::App app{
      "skinserve-load: throughput, latency and capacity of each backend through the "
      "real service"};
  AddConnectionOptions(app, o);
  AddMeshOptions(app, o);
  AddRunOptions(app, o);
  AddSearchOptions(app, o);
  AddMeasurementFlags(app, o.measurement);
  app.add_option("--json", o.json, "write results as JSON");
  app.add_option("--csv", o.csv, "write results as CSV");
  app.add_option("--plot", o.plot, "write a PNG chart (gnuplot)");
  skinserve::cli::AddVersionFlag(app, "skinserve-load");
  skinserve::cli::AddConfigFile(app, "SKINSERVE_LOAD_CONFIG");
  if (const auto exit_code = skinserve::cli::ParseCommandLine(app, argc, argv)) return *exit_code;
  // Frames arrive all the time: keep their buffers mapped (client/malloc_tuning.h).
  if (!skinserve::client::TuneMallocForStreaming()) {
    fmt::print(stderr, "warning: glibc refused the malloc settings for streaming\n");
  }
  if (const auto exit_code = FinishOptions(app, o)) return *exit_code;
  return RunMain(o);
}
