// Shared by the OpenCL tests: the two OpenCL backends of one runtime for the whole test
// process, and checked frames against the float64 reference.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"

namespace skinserve::testing {

// Compute threads the test runtime is created with: not this machine's core count, so
// the test can tell that PoCL took it.
inline constexpr int kOpenClTestThreads = 3;

// Whether POCL_MAX_PTHREAD_COUNT was set before the runtime was created.
bool PoclThreadsPresetByEnvironment();
// The OpenCL device the tests run on: SKINSERVE_OPENCL_DEVICE, as the server reads it
// ("" when unset: PoCL's CPU device here and in CI).
std::string OpenClTestDevice();
// {opencl, opencl-zerocopy} from MakeOpenClBackends(kOpenClTestThreads,
// OpenClTestDevice()), created once.
const std::vector<std::unique_ptr<Backend>>& OpenClBackends();
// "opencl", "opencl-zerocopy", "opencl-staging": the copy backend of a second runtime
// forced onto the discrete-GPU path (pinned staging, chunks, lanes) even on PoCL, and
// "opencl-coalesced": the copy backend of a third runtime with the GPU's kernels too
// (staged and chunked as "opencl-staging", plus the coalesced vertex order and the palette
// in local memory, kCoalescedLocalPaletteBytes at most, 2 tiles per work-group).
std::vector<std::string> OpenClBackendIds();
// The "opencl-coalesced" runtime's local-palette limit: 77 joints' matrices (the
// synthetic meshes' usual count) are staged, 1024 joints' run the global kernels, so the
// reference cases take both paths.
inline constexpr std::size_t kCoalescedLocalPaletteBytes = 77 * 12 * sizeof(float);
inline constexpr int kCoalescedLocalTiles = 2;
Backend& OpenClBackend(const std::string& id);
// The runtime of "opencl-coalesced", created once (or why it could not be).
Result<std::shared_ptr<OpenClRuntime>> CoalescedTestRuntime();
// A test name from a backend id ("opencl-zerocopy" -> "opencl_zerocopy").
std::string BackendTestName(const ::testing::TestParamInfo<std::string>& param);

// With `tangents`, the mesh has normals and tangents.
std::shared_ptr<const Mesh> SyntheticMesh(uint32_t vertices, uint32_t influences, uint32_t joints,
                                          bool normals, uint64_t seed, bool tangents = false);

// "" when `positions` (and `normals` and `tangents`, unless empty) match the float64
// reference for `palette`; else what differs, by how much, and where.
std::string ReferenceMismatch(const Mesh& mesh, std::span<const float> palette,
                              std::span<const float> positions, std::span<const float> normals,
                              std::span<const float> tangents = {});

// Skips the current test when the backend cannot run here, naming the reason.
#define SKIP_IF_OPENCL_UNAVAILABLE(backend)                                  \
  if (!(backend).info().available) {                                         \
    GTEST_SKIP() << (backend).info().id                                      \
                 << " unavailable: " << (backend).info().unavailable_reason; \
  }

}  // namespace skinserve::testing
