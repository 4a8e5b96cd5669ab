// The engine the server-side fuzz targets run against: the serial backend only (no threads
// pools or devices to start per input) and small limits, so that a header cannot make the
// fuzzer allocate gigabytes before the chunks are checked.
#pragma once

#include <cstdlib>
#include <memory>

#include "skinserve/engine/engine.h"

namespace skinserve::fuzz {

inline constexpr uint32_t kMaxVertices = 4096;
inline constexpr uint32_t kMaxJoints = 64;

inline Engine& FuzzEngine() {
  static Engine* engine = [] {
    EngineOptions options;
    options.compute_threads = 1;
    options.queue_capacity = 4;
    options.mesh_budget_bytes = 8ull << 20;
    options.mesh.limits.max_vertices = kMaxVertices;
    options.mesh.limits.max_joints = kMaxJoints;
    options.enabled_backends = {"serial"};
    auto created = Engine::Create(options);
    if (!created.ok()) std::abort();
    return created.value().release();  // lives for the process, like the server's
  }();
  return *engine;
}

}  // namespace skinserve::fuzz
