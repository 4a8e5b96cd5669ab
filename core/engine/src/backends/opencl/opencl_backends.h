// Internal: the two OpenCL backends over one shared runtime.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// `threads`: host threads one frame occupies.
BackendInfo OpenClBackendInfo(const OpenClRuntime& runtime, const char* id, const char* description,
                              int threads);
class OpenClEncoder;
// Both backends of one runtime share its encoder (opencl_encode.h).
std::unique_ptr<Backend> MakeOpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                               std::shared_ptr<OpenClEncoder> encoder);
std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                                   std::shared_ptr<OpenClEncoder> encoder);
// {opencl, opencl-zerocopy} over one runtime created with `options` (MakeOpenClBackends of
// backend_factories.h with every option: the tests' coalesced and local-palette paths on
// PoCL, the benchmark's rows without the local palette); unavailable with the reason when
// the runtime cannot be created.
std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(const OpenClRuntimeOptions& options);
// {opencl, opencl-zerocopy} over `runtime`; or both unavailable with `reason`.
std::vector<std::unique_ptr<Backend>> MakeOpenClBackendsOn(std::shared_ptr<OpenClRuntime> runtime);
std::vector<std::unique_ptr<Backend>> MakeUnavailableOpenClBackends(const std::string& reason);

}  // namespace skinserve
