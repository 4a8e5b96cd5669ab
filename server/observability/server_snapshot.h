// ServerSnapshot: everything the server reports about itself, taken in one place
// (SkinningService::Snapshot) and rendered twice: as Prometheus text on /metrics
// (metrics_text.cpp) and as the ServerStats message of GetServerStats (ToWire,
// rpc/server_messages.h). Whatever one of them shows, the other shows too.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "observability/metrics_frames.h"
#include "rpc/open_uploads.h"
#include "shm/region_registry.h"
#include "skinserve/engine/engine.h"

namespace skinserve::server {

struct InflightStats {
  uint64_t budget_bytes = 0;
  uint64_t bytes = 0;
  uint64_t refused = 0;  // frames refused for want of budget
};

// The engine's animation store (skeletons and compact clips) and its budget.
struct AnimationStoreStats {
  uint64_t skeletons = 0;
  uint64_t clips = 0;
  uint64_t bytes = 0;
  uint64_t budget_bytes = 0;
};

// The frame socket (socket/frame_socket.h); all 0 when it is off.
struct FrameSocketStats {
  uint64_t connections = 0;  // open now
  uint64_t refused = 0;      // over --frame-socket-max-connections
  uint64_t requests = 0;     // read, frames and ticks
};

struct ServerSnapshot {
  std::string version;
  bool serving = false;  // false while starting and while draining
  std::size_t open_streams = 0;
  uint64_t streams_ended_idle = 0;  // by the server's --stream-idle-seconds
  InflightStats inflight;
  UploadStats uploads;
  bool shared_memory = false;  // --shm-dir set; then `regions` holds
  RegionStats regions;
  EngineStats engine;                                 // empty while starting
  std::map<std::string, BackendFrameMetrics> frames;  // per-frame histograms, by backend
  TickCounts ticks;                                   // ticks and their characters read
  FrameSocketStats frame_socket;
  AnimationStoreStats animations;  // empty while starting
};

}  // namespace skinserve::server
