#include "opencl_test_support.h"

#include <cstdlib>
#include <sstream>

#include "backends/common/backend_factories.h"
#include "backends/opencl/opencl_backends.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {

// Read before anything creates the runtime (static initialisation of this file).
static const bool kPoclThreadsPreset = std::getenv("POCL_MAX_PTHREAD_COUNT") != nullptr;

bool PoclThreadsPresetByEnvironment() { return kPoclThreadsPreset; }

std::string OpenClTestDevice() {
  const char* device = std::getenv("SKINSERVE_OPENCL_DEVICE");
  return device == nullptr ? "" : device;
}

const std::vector<std::unique_ptr<Backend>>& OpenClBackends() {
  static const auto* backends = new std::vector<std::unique_ptr<Backend>>(
      MakeOpenClBackends(kOpenClTestThreads, OpenClTestDevice()));
  return *backends;
}

std::vector<std::string> OpenClBackendIds() {
  return {"opencl", "opencl-zerocopy", "opencl-staging", "opencl-coalesced"};
}

Backend& OpenClBackend(const std::string& id) {
  if (id == "opencl-staging") {
    static const auto* staged = new std::vector<std::unique_ptr<Backend>>(
        MakeOpenClBackends(kOpenClTestThreads, OpenClTestDevice(), /*force_staging=*/true));
    return *staged->front();
  }
  if (id == "opencl-coalesced") {
    static Backend* coalesced = [] {
      auto runtime = CoalescedTestRuntime();
      auto* backends = new std::vector<std::unique_ptr<Backend>>(
          runtime.ok() ? MakeOpenClBackendsOn(*runtime)
                       : MakeUnavailableOpenClBackends(runtime.status().message()));
      return backends->front().get();
    }();
    return *coalesced;
  }
  for (const auto& backend : OpenClBackends()) {
    if (backend->info().id == id) return *backend;
  }
  ADD_FAILURE() << "MakeOpenClBackends returned no backend '" << id << "'";
  std::abort();
}

Result<std::shared_ptr<OpenClRuntime>> CoalescedTestRuntime() {
  // The GPU's whole path on any device: staging in chunks of 1024+ vertices (chunks start
  // at multiples of 256, not of a 2-tile group's 512), the coalesced order, and the local
  // palette where it fits.
  static const auto* runtime = new Result<std::shared_ptr<OpenClRuntime>>(
      OpenClRuntime::Create({.threads = kOpenClTestThreads,
                             .device = OpenClTestDevice(),
                             .force_staging = true,
                             .max_chunks = 8,
                             .min_chunk_vertices = 1024,
                             .force_coalesced = true,
                             .local_palette_max_bytes = kCoalescedLocalPaletteBytes,
                             .local_tiles = kCoalescedLocalTiles}));
  return *runtime;
}

std::string BackendTestName(const ::testing::TestParamInfo<std::string>& param) {
  std::string name = param.param;
  for (char& ch : name) {
    if (ch == '-') ch = '_';
  }
  return name;
}

std::shared_ptr<const Mesh> SyntheticMesh(uint32_t vertices, uint32_t influences, uint32_t joints,
                                          bool normals, uint64_t seed, bool tangents) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = vertices,
                                              .influences = influences,
                                              .joint_count = joints,
                                              .normals = normals || tangents,
                                              .tangents = tangents,
                                              .seed = seed}));
  if (!mesh.ok()) {
    ADD_FAILURE() << "synthetic mesh: " << mesh.status().ToString();
    std::abort();
  }
  return *mesh;
}

std::string ReferenceMismatch(const Mesh& mesh, std::span<const float> palette,
                              std::span<const float> positions, std::span<const float> normals,
                              std::span<const float> tangents) {
  const Deviation d = CompareWithReference(mesh, palette, positions, normals,
                                           SkinningMethod::kLinear, {}, tangents);
  if (d.within_tolerance()) return "";
  std::ostringstream out;
  out << "position error " << d.max_position_error << " (tolerance " << d.position_tolerance
      << "), normal error " << d.max_normal_error << " (tolerance " << d.normal_tolerance
      << "), tangent error " << d.max_tangent_error << " (tolerance " << d.tangent_tolerance
      << "), worst vertex " << d.worst_vertex;
  return out.str();
}

}  // namespace skinserve::testing
