// skinserve-frame-profile: what one StreamSkin frame costs each side of a loopback stream.
// Starts a real server process (with the allocation counter preloaded) or measures one
// already running (--target and --server-pid), streams frames through the client library's
// StreamFrames, and after a warm-up reports per frame: minor page faults, heap allocations
// and CPU time of the server process (/proc/PID/stat and its shared counters file) and of
// this client process (getrusage and the counter linked in ahead of libc).
#include <fcntl.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.h"
#include "skinserve/cli/version.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/malloc_tuning.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/reference/synthetic.h"

namespace {

using namespace skinserve;

struct Sample {
  double minor_faults = 0;
  double allocations = 0;
  double bytes = 0;
  double cpu_seconds = 0;
};

Sample operator-(const Sample& a, const Sample& b) {
  return {a.minor_faults - b.minor_faults, a.allocations - b.allocations, a.bytes - b.bytes,
          a.cpu_seconds - b.cpu_seconds};
}

Sample ClientSample() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  const skinserve_alloc_counts* c = skinserve_alloc_counters();
  const auto seconds = [](const timeval& t) { return t.tv_sec + t.tv_usec / 1e6; };
  return {static_cast<double>(u.ru_minflt),
          static_cast<double>(__atomic_load_n(&c->allocations, __ATOMIC_RELAXED)),
          static_cast<double>(__atomic_load_n(&c->bytes, __ATOMIC_RELAXED)),
          seconds(u.ru_utime) + seconds(u.ru_stime)};
}

// The server: /proc/PID/stat (fields 10 minflt, 14 utime, 15 stime, whole process) and
// the counters file its preloaded shim writes (absent: allocations read as 0).
class ServerProbe {
 public:
  ServerProbe(pid_t pid, const std::string& counters_path) : pid_(pid) {
    if (counters_path.empty()) return;
    const int fd = open(counters_path.c_str(), O_RDONLY);
    if (fd < 0) return;
    void* p = mmap(nullptr, sizeof(skinserve_alloc_counts), PROT_READ, MAP_SHARED, fd, 0);
    close(fd);
    if (p != MAP_FAILED) counts_ = static_cast<const skinserve_alloc_counts*>(p);
  }
  bool counting() const { return counts_ != nullptr; }

  Sample Read() const {
    std::ifstream in(fmt::format("/proc/{}/stat", pid_));
    std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Sample s;
    const std::size_t close_paren = stat.rfind(')');  // the command name may hold spaces
    if (close_paren == std::string::npos) return s;
    std::istringstream fields(stat.substr(close_paren + 2));
    std::vector<std::string> f((std::istream_iterator<std::string>(fields)),
                               std::istream_iterator<std::string>());
    if (f.size() < 13) return s;
    // f[0] is field 3 (state): field n is f[n - 3].
    const double tick = static_cast<double>(sysconf(_SC_CLK_TCK));
    s.minor_faults = std::stod(f[10 - 3]);
    s.cpu_seconds = (std::stod(f[14 - 3]) + std::stod(f[15 - 3])) / tick;
    if (counts_ != nullptr) {
      s.allocations = static_cast<double>(__atomic_load_n(&counts_->allocations, __ATOMIC_RELAXED));
      s.bytes = static_cast<double>(__atomic_load_n(&counts_->bytes, __ATOMIC_RELAXED));
    }
    return s;
  }

 private:
  pid_t pid_;
  const skinserve_alloc_counts* counts_ = nullptr;
};

int FreeLoopbackPort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof a;
  int port = 0;
  if (bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&a), &length) == 0) {
    port = ntohs(a.sin_port);
  }
  close(fd);
  return port;
}

// Starts `server` with `args` plus --listen, the counter shim preloaded.
pid_t StartServer(const std::string& server, const std::string& args, const std::string& listen,
                  const std::string& shim, const std::string& counters) {
  std::vector<std::string> argv_strings = {server, "--listen", listen};
  std::istringstream words(args);
  for (std::string w; words >> w;) argv_strings.push_back(w);
  const pid_t pid = fork();
  if (pid != 0) return pid;
  if (!shim.empty()) setenv("LD_PRELOAD", shim.c_str(), 1);
  setenv("SKINSERVE_ALLOC_COUNTERS", counters.c_str(), 1);
  std::vector<char*> argv;
  for (std::string& s : argv_strings) argv.push_back(s.data());
  argv.push_back(nullptr);
  execv(server.c_str(), argv.data());
  _exit(127);
}

struct Options {
  std::string server;       // a skinserve binary to start
  std::string server_args;  // extra arguments for it
  std::string shim = SKINSERVE_ALLOC_COUNTER_PATH;
  std::string target;  // or an already running server...
  int server_pid = 0;  // ...and its pid
  std::string server_counters;
  std::string backend = "sse";
  uint32_t vertices = 25'000, bones = 2, joints = 77;
  bool normals = false;
  std::string encoding = "float32";
  uint32_t instances = 1;
  int window = 4;
  uint64_t warmup = 500, frames = 2000;
  std::string malloc = "tuned";  // this client's glibc malloc: "tuned" or "default"
};

void PrintRow(const char* side, const Sample& d, double frames, bool allocations_known) {
  fmt::print("{:<8} {:>14.3f} {:>14} {:>16} {:>14.1f}\n", side, d.minor_faults / frames,
             allocations_known ? fmt::format("{:.2f}", d.allocations / frames) : "-",
             allocations_known ? fmt::format("{:.0f}", d.bytes / frames) : "-",
             d.cpu_seconds / frames * 1e6);
}

// Frame f's K palettes back to back, from a few distinct poses.
std::vector<std::vector<float>> FramePalettes(const Options& o) {
  std::vector<std::vector<float>> palettes(8);
  for (std::size_t p = 0; p < palettes.size(); ++p) {
    for (uint32_t k = 0; k < o.instances; ++k) {
      const std::vector<float> one = MakeSyntheticPalette(o.joints, 11, p * 31 + k);
      palettes[p].insert(palettes[p].end(), one.begin(), one.end());
    }
  }
  return palettes;
}

// Uploads the mesh, streams the frames, and prints the per-frame table of both sides
// sampled after the warm-up; 1 (the error printed) when a frame fails.
int Profile(client::SkinClient& client, const Options& o, VertexEncoding encoding, pid_t pid,
            const std::string& counters) {
  const MeshArrays mesh = MakeSyntheticMesh({.vertex_count = o.vertices,
                                             .influences = o.bones,
                                             .joint_count = o.joints,
                                             .normals = o.normals,
                                             .seed = 11});
  auto info = client.Upload(mesh);
  if (!info.ok()) return fmt::print(stderr, "error: {}\n", info.status().ToString()), 1;
  const std::vector<std::vector<float>> palettes = FramePalettes(o);
  ServerProbe server(pid, counters);
  Sample client_start, server_start, client_end, server_end;
  uint64_t answered = 0, failed = 0, wrong_size = 0;
  const std::size_t expected = 3ull * o.vertices * o.instances;
  client::StreamSummary summary;
  Status streamed = client::StreamFrames(
      client,
      {.mesh_id = info->mesh_id(),
       .backend = o.backend,
       .want_normals = o.normals,
       .encoding = encoding,
       .instances = o.instances,
       .frames = o.warmup + o.frames,
       .window = o.window},
      [&](uint64_t f) -> const std::vector<float>& { return palettes[f % palettes.size()]; },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        if (!r.status.ok()) {
          if (failed++ == 0) fmt::print(stderr, "frame failed: {}\n", r.status.ToString());
          return;
        }
        wrong_size += r.positions.size() != expected;
        if (++answered == o.warmup) {
          server_start = server.Read();
          client_start = ClientSample();
        }
      },
      &summary);
  client_end = ClientSample();
  server_end = server.Read();
  if (!streamed.ok() || failed > 0 || wrong_size > 0 || answered <= o.warmup) {
    fmt::print(stderr, "error: {} ({} frames failed, {} of the wrong size)\n", streamed.ToString(),
               failed, wrong_size);
    return 1;
  }
  const double measured = static_cast<double>(answered - o.warmup);
  fmt::print(
      "per frame, {:.0f} frames after {} warm-up: {} vertices x {} bones{}, {}, {} "
      "instance(s), backend {}, window {}, client malloc {}\n",
      measured, o.warmup, o.vertices, o.bones, o.normals ? " + normals" : "", o.encoding,
      o.instances, o.backend, o.window, o.malloc);
  fmt::print("{:<8} {:>14} {:>14} {:>16} {:>14}\n", "side", "minor faults", "allocations",
             "alloc bytes", "CPU us");
  PrintRow("client", client_end - client_start, measured, true);
  PrintRow("server", server_end - server_start, measured, server.counting());
  return 0;
}

int Run(const Options& o) {
  const auto encoding = ParseVertexEncoding(o.encoding);
  if (!encoding) return fmt::print(stderr, "error: --encoding {} is unknown\n", o.encoding), 2;
  pid_t pid = o.server_pid;
  std::string target = o.target, counters = o.server_counters;
  bool started = false;
  if (!o.server.empty()) {
    target = fmt::format("127.0.0.1:{}", FreeLoopbackPort());
    counters = fmt::format("/tmp/skinserve-profile-{}.counters", getpid());
    pid = StartServer(o.server, o.server_args, target, o.shim, counters);
    started = true;
  } else if (target.empty() || pid <= 0) {
    return fmt::print(stderr, "error: give --server, or --target with --server-pid\n"), 2;
  }
  int code = 0;
  {
    client::SkinClient client(client::MakeChannel(target));
    if (Status s = client::WaitUntilServing(client.channel(), std::chrono::seconds(20)); !s.ok()) {
      fmt::print(stderr, "error: {}: {}\n", target, s.ToString());
      code = 1;
    } else {
      code = Profile(client, o, *encoding, pid, counters);
    }
  }
  if (started) {
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    unlink(counters.c_str());
  }
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "skinserve-frame-profile: minor page faults, heap allocations and CPU time per "
      "StreamSkin frame, server and client side"};
  app.add_option("--server", o.server, "skinserve binary to start (on a free loopback port)");
  app.add_option("--server-args", o.server_args, "its extra arguments, e.g. '--threads 1'");
  app.add_option("--alloc-counter", o.shim, "the counting shim preloaded into the server")
      ->capture_default_str();
  app.add_option("--target", o.target, "a running server instead of --server...");
  app.add_option("--server-pid", o.server_pid, "...its pid (faults and CPU from /proc)");
  app.add_option("--server-counters", o.server_counters,
                 "...and its SKINSERVE_ALLOC_COUNTERS file, if it runs with the shim");
  app.add_option("--backend", o.backend)->capture_default_str();
  app.add_option("--vertices", o.vertices)->capture_default_str();
  app.add_option("--bones", o.bones)->capture_default_str();
  app.add_option("--joints", o.joints)->capture_default_str();
  app.add_flag("--normals", o.normals);
  app.add_option("--encoding", o.encoding, "float32, float16 or snorm16")->capture_default_str();
  app.add_option("--instances", o.instances, "palettes per request (crowd batch)")
      ->capture_default_str();
  app.add_option("--window", o.window)->capture_default_str();
  app.add_option("--warmup", o.warmup, "frames before measuring")->capture_default_str();
  app.add_option("--frames", o.frames, "frames measured")->capture_default_str();
  app.add_option("--malloc", o.malloc,
                 "this client's glibc malloc: 'tuned' (TuneMallocForStreaming, as "
                 "skinserve-load) or glibc's 'default'")
      ->check(CLI::IsMember({"tuned", "default"}))
      ->capture_default_str();
  skinserve::cli::AddVersionFlag(app, "skinserve-frame-profile");
  CLI11_PARSE(app, argc, argv);
  if (o.malloc == "tuned" && !client::TuneMallocForStreaming()) {
    fmt::print(stderr, "error: glibc refused the malloc settings\n");
    return 1;
  }
  return Run(o);
}
