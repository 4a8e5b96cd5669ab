// `sse-openmp`: the SSE loop, its vertices split across the compute threads.
#include <utility>

#include "backends/common/backend_factories.h"
#include "backends/common/cpu_backend.h"
#include "backends/common/cpu_model.h"
#if defined(__SSE2__)
#include "backends/sse/sse_dual_quaternion_skinning.h"
#include "backends/sse/sse_skinning.h"
#else
#include "backends/common/unavailable_backend.h"
#endif

namespace skinserve {

std::unique_ptr<Backend> MakeSseOpenMpBackend(int threads) {
  BackendInfo info{.id = "sse-openmp",
                   .description = "the SSE loop across threads with OpenMP",
                   .device = CpuModelName(),
                   .simd_width = 4,
                   .threads = threads};
#if defined(__SSE2__)
  return std::make_unique<CpuBackend<sse::SseKernel, sse::SseDualQuaternionKernel>>(
      std::move(info));
#else
  // The paper's SSE2 loop is x86 only: listed, with the reason, elsewhere (Arm runs `simd`).
  info.unavailable_reason = kSseNeedsX86;
  return std::make_unique<UnavailableBackend>(std::move(info));
#endif
}

}  // namespace skinserve
