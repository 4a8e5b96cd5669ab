// One load run: `streams` concurrent StreamSkin streams on one backend, closed loop (each
// keeps `window` frames in flight) or open loop (`rate` frames per second per stream, on
// schedule whatever the answers do). A stream's frames may be ticks of N characters
// (characters_per_tick), then every count and latency of a frame is of a tick.
#pragma once

#include <functional>
#include <string>

#include "arrivals.h"
#include "frame_inputs.h"
#include "load_stats.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "workload.h"

namespace skinserve::load {

struct RunConfig {
  std::string target = "127.0.0.1:50051";
  client::ChannelOptions channel;  // TLS and keepalive
  client::CallLimits limits;       // deadlines, and the streams' idle limit
  std::string backend;
  int streams = 2;
  int window = 4;
  double duration_seconds = 3;  // measured time, after the warm-up (when frames == 0)
  double warmup_seconds = 1;    // answers before this are not counted (errors are)
  uint64_t frames = 0;          // > 0: measure this many frames per stream, not a duration
  double rate = 0;              // frames/s per stream; 0: closed loop
  Arrivals arrivals = Arrivals::kConstant;  // open loop: when each stream sends
  uint64_t arrivals_seed = 1;               // --arrivals poisson: the gaps' generator
  uint64_t check_every = 0;                 // compare every Nth answer with the float64 reference
  VertexEncoding encoding = VertexEncoding::kFloat32;  // of the answers
  uint32_t instances = 1;  // crowd batches: palettes per request, characters per stream
  // Ticks: N characters per request, each its own mesh (RunLoad's meshes[c]); 0: frames of
  // meshes[0].
  uint32_t characters_per_tick = 0;
  // Streams share a TCP connection this many at a time (each further group its own): a
  // server works one connection's HTTP/2 on one thread at a time, so a pool of connections
  // spreads heavy streams over its cores (gRPC's performance guide says the same).
  int streams_per_connection = 8;
  // Same host: each stream's answers are written into a shared-memory region of its own
  // (created in shm_dir, which must be the server's --shm-dir) instead of sent over gRPC.
  bool shared_memory = false;
  // Crowds over gRPC: parts go out as their instances are skinned (SkinRequest.early_parts).
  bool early_parts = false;
  std::string shm_dir = "/dev/shm";
  // Open loop: the streams' requests go to the server's frame socket at this path instead
  // of StreamSkin (the `socket` data plane: with shared_memory, nothing but control on gRPC).
  std::string frame_socket;
};

// Called now and then with the fraction done (for a progress bar).
using Progress = std::function<void(double fraction)>;

// Called on RunLoad's own thread around the measured part, e.g. to scrape the server's
// /metrics: `begin` before the first measured frame can be answered (with no warm-up, before
// the streams open; else when the warm-up ends, the frames then in flight straddling it),
// `end` after the last answer, once every stream has ended. Either may be empty.
struct MeasuredPartHooks {
  std::function<void()> begin, end;
};

// `meshes`: the uploaded mesh of frames (one), or one per character of a tick
// (config.characters_per_tick of them).
RunResult RunLoad(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                  const Progress& progress, const MeasuredPartHooks& hooks = {});

}  // namespace skinserve::load
