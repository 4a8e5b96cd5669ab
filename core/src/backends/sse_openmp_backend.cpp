// `sse-openmp`: the SSE loop, its vertices split across the compute threads.
#include "backend_factories.h"
#include "cpu_backend.h"
#include "cpu_model.h"
#include "sse_dual_quaternion_skinning.h"
#include "sse_skinning.h"

namespace skinserve {

std::unique_ptr<Backend> MakeSseOpenMpBackend(int threads) {
  return std::make_unique<CpuBackend<sse::SseKernel, sse::SseDualQuaternionKernel>>(
      BackendInfo{.id = "sse-openmp",
                  .description = "the SSE loop across threads with OpenMP",
                  .device = CpuModelName(),
                  .simd_width = 4,
                  .threads = threads});
}

}  // namespace skinserve
