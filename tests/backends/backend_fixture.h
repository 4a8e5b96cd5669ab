// Shared by the backend tests: every backend, created once per test process (the OpenCL
// program is built once), and a helper that skins a frame into fresh outputs.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve::testing {

// All backends, as CreateAllBackends returns them, for the whole test process.
const std::vector<std::unique_ptr<Backend>>& AllBackends();
Backend& BackendById(const std::string& id);
// The paper's SSE backends exist on x86 only; elsewhere they are listed unavailable (with
// the reason, checked in backend_properties_test) and left out of the per-backend tests.
#if defined(__SSE2__)
inline constexpr bool kSseBackendsRunHere = true;
#else
inline constexpr bool kSseBackendsRunHere = false;
#endif
inline bool IsSseBackend(const std::string& id) { return id == "sse" || id == "sse-openmp"; }

// Ids of every backend that computes (all but passthrough), available or not; the SSE
// ones only where they run.
std::vector<std::string> ComputingBackendIds();

struct Output {
  std::vector<float> positions;
  std::vector<float> normals;
};

// Skins `palette` with `backend` into outputs pre-filled with NaN (so an unwritten
// element shows up as an error).
Output SkinOnce(Backend& backend, const PreparedMesh& prepared, std::span<const float> palette,
                bool with_normals, SkinningMethod method = SkinningMethod::kLinear);
// Ids of every backend whose info() lists `method`, available or not.
std::vector<std::string> BackendIdsWithMethod(SkinningMethod method);

// Skips the current test when the backend cannot run here, naming the reason.
#define SKIP_IF_UNAVAILABLE(backend)                                         \
  if (!(backend).info().available) {                                         \
    GTEST_SKIP() << (backend).info().id                                      \
                 << " unavailable: " << (backend).info().unavailable_reason; \
  }

}  // namespace skinserve::testing
