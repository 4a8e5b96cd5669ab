// BM_SkinDeviceOutput/opencl/<vertices>/<bones> (skinserve-bench --device-output): the
// `opencl` backend's frame with its output left on the device, the GPU regions' path
// (SkinFrame::device, docs/serving/gpu-regions.md): the palette uploaded, the kernel, the
// device-to-device copy into the output memory, waited for; nothing read back. Figure 5's
// fourth curve, beside `opencl`'s frame read back (BM_Skin/opencl). Device memory of the
// runtime's own context stands for a renderer's imported buffer: the same kernel and copy,
// without an imported buffer's acquire and release (nothing to import from on PoCL or in a
// benchmark without a Vulkan client). BM_SkinDeviceOutputInPlace/opencl/<vertices>/<bones>:
// the same frame written in place (the kernel into a sub-buffer of the memory, no copy), as
// imported memory is; plain memory takes the copies in the service.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "workload_cache.h"

namespace skinserve::bench {

// Registers the rows over `vertices` x `bones` on an OpenCL runtime of its own (`threads`
// lanes, on `opencl_device` as --opencl-device names it, its queues profiled when
// `device_timing`). False, the reason printed, when that runtime or its `opencl` backend is
// unavailable. `tick` > 0: also BM_SkinTickDeviceOutput/opencl/<vertices>/<bones>/
// characters:N, a tick of N distinct meshes skinned together (Backend::SkinFrames) into
// their ranges of one device memory (a GPU region's tick, issue 44).
bool RegisterDeviceOutputRows(WorkloadCache& cache, const std::vector<uint32_t>& vertices,
                              const std::vector<uint32_t>& bones, int threads,
                              const std::string& opencl_device, bool device_timing, uint32_t tick);

}  // namespace skinserve::bench
