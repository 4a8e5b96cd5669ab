// Internal: one factory per backend source file; CreateAllBackends() calls them in order.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve {

std::unique_ptr<Backend> MakeSerialBackend();
std::unique_ptr<Backend> MakeOpenMpBackend(int threads);
// `sse` and `sse-openmp` are SSE2, which only x86 has; elsewhere they are unavailable with
// this reason.
inline constexpr char kSseNeedsX86[] =
    "SSE2 is an x86 instruction set and this CPU is not x86 (the `simd` backends run here)";
std::unique_ptr<Backend> MakeSseBackend();
std::unique_ptr<Backend> MakeSseOpenMpBackend(int threads);
// `simd` (threads <= 0) or `simd-openmp` (on `threads` threads), capped by
// $SKINSERVE_SIMD_MAX_TARGET when set.
std::unique_ptr<Backend> MakeSimdBackend(int threads);
// {opencl, opencl-zerocopy}: one shared context, device, lanes and built program on the
// device `device` chooses (see OpenClRuntimeOptions). When no OpenCL platform or device
// is present, or none matches `device`, both are returned unavailable, with the reason.
// `force_staging`: the discrete-GPU transfer path even on a CPU device, in chunks of 1024
// vertices and more (tests). `device_timing`: frames report their device time
// (OpenClRuntimeOptions::device_timing).
std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(int threads,
                                                         const std::string& device = "",
                                                         bool force_staging = false,
                                                         bool device_timing = false);
std::unique_ptr<Backend> MakePassthroughBackend();

}  // namespace skinserve
