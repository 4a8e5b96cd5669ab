// Internal: the two OpenCL backends over one shared runtime.
#pragma once

#include <memory>

#include "opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// `threads`: host threads one frame occupies.
BackendInfo OpenClBackendInfo(const OpenClRuntime& runtime, const char* id, const char* description,
                              int threads);
std::unique_ptr<Backend> MakeOpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime);
std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime);

}  // namespace skinserve
