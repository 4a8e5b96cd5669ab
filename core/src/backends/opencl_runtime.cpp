#include "opencl_runtime.h"

#include <fmt/format.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "skinserve/core/synthetic.h"
#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {
namespace {

constexpr std::size_t kWorkGroupSize = 64;

std::string DeviceString(cl_device_id device, cl_device_info what) {
  std::size_t size = 0;
  if (clGetDeviceInfo(device, what, 0, nullptr, &size) != CL_SUCCESS || size == 0) return "";
  std::string value(size, '\0');
  clGetDeviceInfo(device, what, size, value.data(), nullptr);
  while (!value.empty() && value.back() == '\0') value.pop_back();
  return value;
}

}  // namespace

const char* ClErrorName(cl_int code) {
  switch (code) {
#define SKINSERVE_CL_ERROR(name) \
  case name:                     \
    return #name;
    SKINSERVE_CL_ERROR(CL_SUCCESS)
    SKINSERVE_CL_ERROR(CL_DEVICE_NOT_FOUND)
    SKINSERVE_CL_ERROR(CL_DEVICE_NOT_AVAILABLE)
    SKINSERVE_CL_ERROR(CL_COMPILER_NOT_AVAILABLE)
    SKINSERVE_CL_ERROR(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    SKINSERVE_CL_ERROR(CL_OUT_OF_RESOURCES)
    SKINSERVE_CL_ERROR(CL_OUT_OF_HOST_MEMORY)
    SKINSERVE_CL_ERROR(CL_BUILD_PROGRAM_FAILURE)
    SKINSERVE_CL_ERROR(CL_MAP_FAILURE)
    SKINSERVE_CL_ERROR(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    SKINSERVE_CL_ERROR(CL_INVALID_VALUE)
    SKINSERVE_CL_ERROR(CL_INVALID_PLATFORM)
    SKINSERVE_CL_ERROR(CL_INVALID_DEVICE)
    SKINSERVE_CL_ERROR(CL_INVALID_CONTEXT)
    SKINSERVE_CL_ERROR(CL_INVALID_COMMAND_QUEUE)
    SKINSERVE_CL_ERROR(CL_INVALID_HOST_PTR)
    SKINSERVE_CL_ERROR(CL_INVALID_MEM_OBJECT)
    SKINSERVE_CL_ERROR(CL_INVALID_BUFFER_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_PROGRAM)
    SKINSERVE_CL_ERROR(CL_INVALID_PROGRAM_EXECUTABLE)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL_NAME)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_INDEX)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_VALUE)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL_ARGS)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_DIMENSION)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_GROUP_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_ITEM_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_GLOBAL_WORK_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_EVENT_WAIT_LIST)
    SKINSERVE_CL_ERROR(CL_INVALID_OPERATION)
#undef SKINSERVE_CL_ERROR
    case -1001:  // the ICD loader found no platform at all
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "CL_UNKNOWN_ERROR";
  }
}

Status ClError(const char* call, cl_int code) {
  return Internal(fmt::format("{} failed: {} ({})", call, ClErrorName(code), code));
}

Result<std::shared_ptr<OpenClRuntime>> OpenClRuntime::Create(int threads) {
  // PoCL sizes its worker pool when the platform loads: match the engine's threads.
  setenv("POCL_MAX_PTHREAD_COUNT", std::to_string(threads).c_str(), /*overwrite=*/0);
  cl_uint platform_count = 0;
  cl_int err = clGetPlatformIDs(0, nullptr, &platform_count);
  if (err != CL_SUCCESS || platform_count == 0) {
    return FailedPrecondition(
        fmt::format("no OpenCL platform found (clGetPlatformIDs: {} ({})); install an ICD such as "
                    "pocl-opencl-icd",
                    ClErrorName(err), err));
  }
  std::vector<cl_platform_id> platforms(platform_count);
  clGetPlatformIDs(platform_count, platforms.data(), nullptr);
  cl_device_id device = nullptr;
  for (cl_platform_id platform : platforms) {
    if (clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &device, nullptr) == CL_SUCCESS) break;
    device = nullptr;
  }
  if (device == nullptr) return FailedPrecondition("no OpenCL device found on any platform");

  std::shared_ptr<OpenClRuntime> runtime(new OpenClRuntime());
  runtime->device_ = device;
  runtime->device_name_ = DeviceString(device, CL_DEVICE_NAME);
  runtime->version_ = DeviceString(device, CL_DRIVER_VERSION);
  cl_uint units = 1, width = 1;
  clGetDeviceInfo(device, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof(units), &units, nullptr);
  clGetDeviceInfo(device, CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT, sizeof(width), &width, nullptr);
  runtime->compute_units_ = static_cast<int>(units);
  runtime->vector_width_ = static_cast<int>(width);

  runtime->context_ = clCreateContext(nullptr, 1, &device, nullptr, nullptr, &err);
  if (err != CL_SUCCESS) return ClError("clCreateContext", err);
  runtime->queue_ = clCreateCommandQueue(runtime->context_, device, 0, &err);
  if (err != CL_SUCCESS) return ClError("clCreateCommandQueue", err);

  const char* source = kernels::kLinearBlendSkinningSource.data();
  const std::size_t length = kernels::kLinearBlendSkinningSource.size();
  runtime->program_ = clCreateProgramWithSource(runtime->context_, 1, &source, &length, &err);
  if (err != CL_SUCCESS) return ClError("clCreateProgramWithSource", err);
  err = clBuildProgram(runtime->program_, 1, &device, "-cl-std=CL1.2", nullptr, nullptr);
  if (err != CL_SUCCESS) {
    std::size_t log_size = 0;
    clGetProgramBuildInfo(runtime->program_, device, CL_PROGRAM_BUILD_LOG, 0, nullptr, &log_size);
    std::string log(log_size, '\0');
    clGetProgramBuildInfo(runtime->program_, device, CL_PROGRAM_BUILD_LOG, log_size, log.data(),
                          nullptr);
    return FailedPrecondition(
        fmt::format("clBuildProgram failed: {}; build log:\n{}", ClErrorName(err), log));
  }
  for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
    const std::string name = fmt::format("skin_b{}", b);
    runtime->kernels_[b - 1] = clCreateKernel(runtime->program_, name.c_str(), &err);
    if (err != CL_SUCCESS) return ClError("clCreateKernel", err);
  }
  if (Status s = runtime->Warm(); !s.ok()) return s;
  return runtime;
}

OpenClRuntime::~OpenClRuntime() {
  for (cl_kernel kernel : kernels_) {
    if (kernel != nullptr) clReleaseKernel(kernel);
  }
  if (program_ != nullptr) clReleaseProgram(program_);
  if (queue_ != nullptr) clReleaseCommandQueue(queue_);
  if (context_ != nullptr) clReleaseContext(context_);
}

Result<ClBuffer> OpenClRuntime::CreateBuffer(cl_mem_flags flags, std::size_t bytes,
                                             const void* host) {
  cl_int err = CL_SUCCESS;
  // OpenCL takes a non-const host pointer even for read-only buffers.
  cl_mem mem = clCreateBuffer(context_, flags, bytes, const_cast<void*>(host), &err);
  if (err != CL_SUCCESS) return ClError("clCreateBuffer", err);
  return ClBuffer(mem);
}

Status OpenClRuntime::EnqueueSkin(const Mesh& mesh, const SkinKernelArgs& args, bool with_normals) {
  cl_kernel kernel = kernels_[mesh.influences() - 1];
  // Unused normal arguments still need a valid buffer: the kernel never reads them.
  const cl_mem normals = args.normals != nullptr ? args.normals : args.positions;
  const cl_mem out_normals = args.out_normals != nullptr ? args.out_normals : args.out_positions;
  const cl_uint count = mesh.vertex_count();
  const cl_uint normals_flag = with_normals ? 1 : 0;
  const cl_mem buffers[] = {args.palette, args.positions,     normals,    args.joints,
                            args.weights, args.out_positions, out_normals};
  for (cl_uint i = 0; i < 7; ++i) {
    if (cl_int err = clSetKernelArg(kernel, i, sizeof(cl_mem), &buffers[i]); err != CL_SUCCESS) {
      return ClError("clSetKernelArg", err);
    }
  }
  if (cl_int err = clSetKernelArg(kernel, 7, sizeof(cl_uint), &count); err != CL_SUCCESS) {
    return ClError("clSetKernelArg", err);
  }
  if (cl_int err = clSetKernelArg(kernel, 8, sizeof(cl_uint), &normals_flag); err != CL_SUCCESS) {
    return ClError("clSetKernelArg", err);
  }
  const std::size_t global = (count + kWorkGroupSize - 1) / kWorkGroupSize * kWorkGroupSize;
  const std::size_t local = kWorkGroupSize;
  if (cl_int err =
          clEnqueueNDRangeKernel(queue_, kernel, 1, nullptr, &global, &local, 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel", err);
  }
  return Status::Ok();
}

// PoCL compiles a kernel's work-group function on its first launch: do that now, for
// every influence count, so no client's first frame pays for it.
Status OpenClRuntime::Warm() {
  for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
    auto mesh = Mesh::Create(MakeSyntheticMesh(
        {.vertex_count = kWorkGroupSize, .influences = b, .joint_count = 4, .normals = true}));
    if (!mesh.ok()) return mesh.status();
    const Mesh& m = **mesh;
    const std::vector<float> palette = MakeIdentityPalette(m.joint_count());
    auto in = [&](std::size_t bytes, const void* host) {
      return CreateBuffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, bytes, host);
    };
    auto p = in(palette.size() * sizeof(float), palette.data());
    auto pos = in(m.positions().size_bytes(), m.positions().data());
    auto nrm = in(m.normals().size_bytes(), m.normals().data());
    auto jnt = in(m.joints().size_bytes(), m.joints().data());
    auto wgt = in(m.weights().size_bytes(), m.weights().data());
    auto out = CreateBuffer(CL_MEM_WRITE_ONLY, m.positions().size_bytes(), nullptr);
    auto out_n = CreateBuffer(CL_MEM_WRITE_ONLY, m.positions().size_bytes(), nullptr);
    for (const auto* r : {&p, &pos, &nrm, &jnt, &wgt, &out, &out_n}) {
      if (!r->ok()) return r->status();
    }
    const SkinKernelArgs args{p->get(),   pos->get(), nrm->get(),  jnt->get(),
                              wgt->get(), out->get(), out_n->get()};
    if (Status s = EnqueueSkin(m, args, true); !s.ok()) return s;
    if (cl_int err = clFinish(queue_); err != CL_SUCCESS) return ClError("clFinish", err);
  }
  return Status::Ok();
}

}  // namespace skinserve
