// `serial`: the paper's optimised scalar loop on one thread, the baseline of every speedup.
// Compiled without auto-vectorisation (core/CMakeLists.txt) so it stays scalar.
#include "backends/common/backend_factories.h"
#include "backends/common/cpu_backend.h"
#include "backends/common/cpu_model.h"
#include "backends/scalar/scalar_dual_quaternion_skinning.h"
#include "backends/scalar/scalar_skinning.h"

namespace skinserve {

std::unique_ptr<Backend> MakeSerialBackend() {
  return std::make_unique<CpuBackend<scalar::ScalarKernel, scalar::ScalarDualQuaternionKernel>>(
      BackendInfo{.id = "serial",
                  .description = "scalar C++ on one thread (the baseline)",
                  .device = CpuModelName()});
}

}  // namespace skinserve
