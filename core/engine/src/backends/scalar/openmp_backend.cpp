// `openmp`: the serial scalar loop, its vertices split across the compute threads.
// Compiled without auto-vectorisation, like `serial`, so the speedup is the threads'.
#include "backends/common/backend_factories.h"
#include "backends/common/cpu_backend.h"
#include "backends/common/cpu_model.h"
#include "backends/scalar/scalar_dual_quaternion_skinning.h"
#include "backends/scalar/scalar_skinning.h"

namespace skinserve {

std::unique_ptr<Backend> MakeOpenMpBackend(int threads) {
  return std::make_unique<CpuBackend<scalar::ScalarKernel, scalar::ScalarDualQuaternionKernel>>(
      BackendInfo{.id = "openmp",
                  .description = "the scalar loop across threads with OpenMP",
                  .device = CpuModelName(),
                  .threads = threads});
}

}  // namespace skinserve
