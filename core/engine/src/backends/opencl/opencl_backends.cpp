#include "backends/opencl/opencl_backends.h"

#include "backends/opencl/opencl_encode.h"

#include <fmt/format.h>

#include <exception>

#include "backends/common/backend_factories.h"
#include "backends/common/unavailable_backend.h"

namespace skinserve {
namespace {

constexpr const char* kCopyId = "opencl";
constexpr const char* kZeroCopyId = "opencl-zerocopy";

}  // namespace

std::vector<std::unique_ptr<Backend>> MakeUnavailableOpenClBackends(const std::string& reason) {
  std::vector<std::unique_ptr<Backend>> backends;
  for (const char* id : {kCopyId, kZeroCopyId}) {
    BackendInfo info;
    info.id = id;
    info.description = "OpenCL";
    info.unavailable_reason = reason;
    backends.push_back(std::make_unique<UnavailableBackend>(std::move(info)));
  }
  return backends;
}

std::vector<std::unique_ptr<Backend>> MakeOpenClBackendsOn(std::shared_ptr<OpenClRuntime> runtime) {
  std::vector<std::unique_ptr<Backend>> backends;
  auto encoder = std::make_shared<OpenClEncoder>(runtime);
  backends.push_back(MakeOpenClCopyBackend(runtime, encoder));
  backends.push_back(MakeOpenClZeroCopyBackend(std::move(runtime), std::move(encoder)));
  return backends;
}

BackendInfo OpenClBackendInfo(const OpenClRuntime& runtime, const char* id, const char* description,
                              int threads) {
  BackendInfo info;
  info.id = id;
  info.description = fmt::format("{} ({})", description, runtime.platform_version());
  if (runtime.local_palette()) {
    info.description += fmt::format("; palettes of up to {} bytes staged in local memory",
                                    runtime.local_palette_bytes());
  }
  info.device = runtime.device_name();
  info.simd_width = runtime.vector_width();
  info.threads = threads;
  // linear_blend_skinning.cl and dual_quaternion_skinning.cl.
  info.methods = {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion};
  info.morph_targets = true;   // morph_targets.cl, before either method's kernels
  info.tangents = true;        // the *_tangents_* kernels, and morphed on the device too
  info.quantized_rest = true;  // quantized_skinning.cl: the device holds the integers only
  info.encoded_outputs = OpenClEncodedOutputs();  // encode_output.cl, after either method
  return info;
}

std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(int threads, const std::string& device,
                                                         bool force_staging, bool device_timing) {
  OpenClRuntimeOptions options{.threads = threads, .device = device};
  options.device_timing = device_timing;
  if (force_staging) {
    // The tests' configuration: small frames run in several chunks too.
    options.force_staging = true;
    options.max_chunks = 8;
    options.min_chunk_vertices = 1024;
  }
  return MakeOpenClBackends(options);
}

std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(const OpenClRuntimeOptions& options) {
  // Never throws: an engine without OpenCL still serves every other backend.
  try {
    auto runtime = OpenClRuntime::Create(options);
    if (!runtime.ok()) return MakeUnavailableOpenClBackends(runtime.status().message());
    return MakeOpenClBackendsOn(*runtime);
  } catch (const std::exception& e) {
    return MakeUnavailableOpenClBackends(fmt::format("OpenCL start-up failed: {}", e.what()));
  }
}

}  // namespace skinserve
