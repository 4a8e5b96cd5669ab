#include "opencl_backends.h"

#include <fmt/format.h>

#include "backend_factories.h"
#include "unavailable_backend.h"

namespace skinserve {

BackendInfo OpenClBackendInfo(const OpenClRuntime& runtime, const char* id,
                              const char* description) {
  BackendInfo info;
  info.id = id;
  info.description = fmt::format("{} (PoCL {})", description, runtime.version());
  info.device = runtime.device_name();
  info.simd_width = runtime.vector_width();
  info.threads = runtime.compute_units();
  return info;
}

std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(int threads) {
  std::vector<std::unique_ptr<Backend>> backends;
  auto runtime = OpenClRuntime::Create(threads);
  if (!runtime.ok()) {
    for (const char* id : {"opencl", "opencl-zerocopy"}) {
      BackendInfo info;
      info.id = id;
      info.description = "OpenCL";
      info.unavailable_reason = runtime.status().message();
      backends.push_back(std::make_unique<UnavailableBackend>(std::move(info)));
    }
    return backends;
  }
  backends.push_back(MakeOpenClCopyBackend(*runtime));
  backends.push_back(MakeOpenClZeroCopyBackend(*runtime));
  return backends;
}

}  // namespace skinserve
