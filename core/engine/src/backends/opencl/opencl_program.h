// Internal: OpenCL programs built from the kernels embedded in the binary
// (skinserve/kernels/embedded_kernels.h, generated from kernels/*.cl at build time).
#pragma once

#include <CL/cl.h>

#include <span>
#include <string>
#include <string_view>

#include "skinserve/model/status.h"

namespace skinserve {

// One program from `sources` in order, built for `device` with `options`; the caller owns
// it. On a build error FAILED_PRECONDITION names `what` and carries the compiler's log.
Result<cl_program> BuildClProgram(cl_context context, cl_device_id device,
                                  std::span<const std::string_view> sources,
                                  const std::string& options, const char* what);

// A skinning program: kernels/skinning_common.cl, then `sources` (the skinning kernels'
// files), as BuildClProgram.
Result<cl_program> BuildSkinningProgram(cl_context context, cl_device_id device,
                                        std::span<const std::string_view> sources,
                                        const std::string& options, const char* what);

}  // namespace skinserve
