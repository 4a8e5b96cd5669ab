// FrameSocketAccess: what a connection of the frame socket (frame_socket.h) serves with,
// taken from the service for the connection's peer when it opens
// (SkinningService::FrameSocketAccessFor): the same engine, default backend, in-flight
// budget, request limits and regions that StreamSkin uses, and the authorization
// policy's verdict on StreamSkin for that peer.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "frames/inflight_budget.h"
#include "frames/skin_request_reader.h"
#include "shm/region_registry.h"
#include "skinserve/engine/engine.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

// What the frame socket counts, for the service's snapshot (/metrics and GetServerStats).
struct FrameSocketCounters {
  std::atomic<uint64_t> connections{0};  // open now
  std::atomic<uint64_t> refused{0};      // over --frame-socket-max-connections
  std::atomic<uint64_t> requests{0};     // read: frames and ticks
};

struct FrameSocketAccess {
  Engine* engine = nullptr;  // null: the server is still building its backends
  Status allowed;            // not OK: the policy denies this peer StreamSkin (the reason)
  std::string default_backend;
  InflightBudget* budget = nullptr;
  SkinRequestLimits limits;
  RegionCaller regions;                     // the peer owns regions as on a unix: gRPC address
  FrameSocketCounters* counters = nullptr;  // the service's; outlives the connection
};

}  // namespace skinserve::server
