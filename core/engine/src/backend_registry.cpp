#include "skinserve/engine/backend_registry.h"

#include <algorithm>

#include "backends/common/backend_factories.h"

namespace skinserve {

std::vector<std::unique_ptr<Backend>> CreateAllBackends(int threads,
                                                        const std::string& opencl_device,
                                                        bool opencl_device_timing) {
  threads = std::max(threads, 1);
  std::vector<std::unique_ptr<Backend>> backends;
  backends.push_back(MakeSerialBackend());
  backends.push_back(MakeOpenMpBackend(threads));
  backends.push_back(MakeSseBackend());
  backends.push_back(MakeSseOpenMpBackend(threads));
  backends.push_back(MakeSimdBackend(0));
  backends.push_back(MakeSimdBackend(threads));
  for (auto& backend : MakeOpenClBackends(threads, opencl_device, false, opencl_device_timing))
    backends.push_back(std::move(backend));
  backends.push_back(MakePassthroughBackend());
  return backends;
}

}  // namespace skinserve
