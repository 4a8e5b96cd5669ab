#include "backends/opencl/opencl_program.h"

#include <fmt/format.h>

#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {

Result<cl_program> BuildClProgram(cl_context context, cl_device_id device,
                                  std::span<const std::string_view> sources,
                                  const std::string& options, const char* what) {
  std::vector<const char*> texts;
  std::vector<std::size_t> lengths;
  for (std::string_view source : sources) {
    texts.push_back(source.data());
    lengths.push_back(source.size());
  }
  cl_int err = CL_SUCCESS;
  cl_program program = clCreateProgramWithSource(context, static_cast<cl_uint>(texts.size()),
                                                 texts.data(), lengths.data(), &err);
  if (err != CL_SUCCESS) {
    return ClError(fmt::format("clCreateProgramWithSource({})", what).c_str(), err);
  }
  err = clBuildProgram(program, 1, &device, options.c_str(), nullptr, nullptr);
  if (err == CL_SUCCESS) return program;
  std::size_t log_size = 0;
  std::string log;
  cl_int log_err =
      clGetProgramBuildInfo(program, device, CL_PROGRAM_BUILD_LOG, 0, nullptr, &log_size);
  if (log_err == CL_SUCCESS) {
    log.resize(log_size);
    log_err =
        clGetProgramBuildInfo(program, device, CL_PROGRAM_BUILD_LOG, log_size, log.data(), nullptr);
  }
  if (log_err != CL_SUCCESS) {
    log = fmt::format("(no log: clGetProgramBuildInfo failed: {} ({}))", ClErrorName(log_err),
                      log_err);
  }
  while (!log.empty() && log.back() == '\0') log.pop_back();
  clReleaseProgram(program);
  return FailedPrecondition(fmt::format("clBuildProgram({}) failed: {} ({}); build log:\n{}", what,
                                        ClErrorName(err), err, log));
}

Result<cl_program> BuildSkinningProgram(cl_context context, cl_device_id device,
                                        std::span<const std::string_view> sources,
                                        const std::string& options, const char* what) {
  // What the skinning kernels share (kernels/skinning_common.cl) is the program's first
  // source string rather than an #include: clCreateProgramWithSource compiles its strings
  // as one text in order (OpenCL 1.2, 5.6.1), so this acts as the include on every
  // compiler from source (PoCL's clang, NVIDIA's), while an #include would make the device
  // compiler look for the file on the serving machine at run time, through an -I path.
  // The common text is embedded at build time like every kernels/*.cl (kernels/CMakeLists.txt).
  std::vector<std::string_view> all = {kernels::kSkinningCommonSource};
  all.insert(all.end(), sources.begin(), sources.end());
  return BuildClProgram(context, device, all, options, what);
}

}  // namespace skinserve
