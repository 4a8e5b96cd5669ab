// Every backend skinserve has, built once per engine (the OpenCL context and program
// included), in the order of the design's table.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve {

// `threads`: compute threads a parallel backend uses for one frame (>= 1).
// Backends that cannot run here are returned too, with available = false and the reason.
// `opencl_device`: which OpenCL device the OpenCL backends use: "" (the first CPU device,
// else the first device), "cpu", "gpu", or part of a platform or device name.
// `opencl_device_timing`: OpenCL frames report their kernel and transfer time (profiled
// queues, which cost a GPU frame time of its own: OpenClRuntimeOptions::device_timing).
std::vector<std::unique_ptr<Backend>> CreateAllBackends(int threads,
                                                        const std::string& opencl_device = "",
                                                        bool opencl_device_timing = false);

}  // namespace skinserve
