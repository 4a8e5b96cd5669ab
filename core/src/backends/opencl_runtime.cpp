#include "opencl_runtime.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {
namespace {

// Vertices one work-item skins; the kernel checks it gets the value it is written for.
constexpr std::size_t kVerticesPerItem = 4;
// Work-items per work-group (256 vertices): past 64, PoCL's per-group cost is noise.
constexpr std::size_t kItemsPerGroup = 64;
// What the ICD loader returns when it finds no platform at all (cl_khr_icd).
constexpr cl_int kPlatformNotFoundKhr = -1001;

Result<std::string> DeviceString(cl_device_id device, cl_device_info what, const char* name) {
  std::size_t size = 0;
  if (cl_int err = clGetDeviceInfo(device, what, 0, nullptr, &size); err != CL_SUCCESS) {
    return ClError(name, err);
  }
  std::string value(size, '\0');
  if (cl_int err = clGetDeviceInfo(device, what, size, value.data(), nullptr); err != CL_SUCCESS) {
    return ClError(name, err);
  }
  while (!value.empty() && value.back() == '\0') value.pop_back();
  return value;
}

Result<std::string> PlatformString(cl_platform_id platform, cl_platform_info what,
                                   const char* name) {
  std::size_t size = 0;
  if (cl_int err = clGetPlatformInfo(platform, what, 0, nullptr, &size); err != CL_SUCCESS) {
    return ClError(name, err);
  }
  std::string value(size, '\0');
  if (cl_int err = clGetPlatformInfo(platform, what, size, value.data(), nullptr);
      err != CL_SUCCESS) {
    return ClError(name, err);
  }
  while (!value.empty() && value.back() == '\0') value.pop_back();
  return value;
}

Status DeviceUint(cl_device_id device, cl_device_info what, const char* name, cl_uint* value) {
  if (cl_int err = clGetDeviceInfo(device, what, sizeof(*value), value, nullptr);
      err != CL_SUCCESS) {
    return ClError(name, err);
  }
  return Status::Ok();
}

struct Picked {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
};

// The first device of the first platform that has one.
Result<Picked> PickDevice() {
  cl_uint platform_count = 0;
  cl_int err = clGetPlatformIDs(0, nullptr, &platform_count);
  if (err == kPlatformNotFoundKhr || (err == CL_SUCCESS && platform_count == 0)) {
    return FailedPrecondition(
        fmt::format("no OpenCL platform found (clGetPlatformIDs: {} ({})); install an ICD such "
                    "as pocl-opencl-icd",
                    ClErrorName(err), err));
  }
  if (err != CL_SUCCESS) return ClError("clGetPlatformIDs", err);
  std::vector<cl_platform_id> platforms(platform_count);
  if (err = clGetPlatformIDs(platform_count, platforms.data(), nullptr); err != CL_SUCCESS) {
    return ClError("clGetPlatformIDs", err);
  }
  std::string failures;
  for (cl_platform_id platform : platforms) {
    cl_device_id device = nullptr;
    err = clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &device, nullptr);
    if (err == CL_SUCCESS) return Picked{platform, device};
    failures += fmt::format("; clGetDeviceIDs: {} ({})", ClErrorName(err), err);
  }
  return FailedPrecondition(
      fmt::format("no OpenCL device found on {} platform(s){}", platform_count, failures));
}

// "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, ..." -> "OpenCL 3.0 PoCL 3.1+debian".
std::string ShortVersion(std::string version) {
  if (auto cut = version.find("  "); cut != std::string::npos) version.resize(cut);
  return version;
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
    SKINSERVE_CL_ERROR(CL_PROFILING_INFO_NOT_AVAILABLE)
    SKINSERVE_CL_ERROR(CL_MEM_COPY_OVERLAP)
    SKINSERVE_CL_ERROR(CL_IMAGE_FORMAT_MISMATCH)
    SKINSERVE_CL_ERROR(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    SKINSERVE_CL_ERROR(CL_BUILD_PROGRAM_FAILURE)
    SKINSERVE_CL_ERROR(CL_MAP_FAILURE)
    SKINSERVE_CL_ERROR(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    SKINSERVE_CL_ERROR(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    SKINSERVE_CL_ERROR(CL_COMPILE_PROGRAM_FAILURE)
    SKINSERVE_CL_ERROR(CL_LINKER_NOT_AVAILABLE)
    SKINSERVE_CL_ERROR(CL_LINK_PROGRAM_FAILURE)
    SKINSERVE_CL_ERROR(CL_DEVICE_PARTITION_FAILED)
    SKINSERVE_CL_ERROR(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    SKINSERVE_CL_ERROR(CL_INVALID_VALUE)
    SKINSERVE_CL_ERROR(CL_INVALID_DEVICE_TYPE)
    SKINSERVE_CL_ERROR(CL_INVALID_PLATFORM)
    SKINSERVE_CL_ERROR(CL_INVALID_DEVICE)
    SKINSERVE_CL_ERROR(CL_INVALID_CONTEXT)
    SKINSERVE_CL_ERROR(CL_INVALID_QUEUE_PROPERTIES)
    SKINSERVE_CL_ERROR(CL_INVALID_COMMAND_QUEUE)
    SKINSERVE_CL_ERROR(CL_INVALID_HOST_PTR)
    SKINSERVE_CL_ERROR(CL_INVALID_MEM_OBJECT)
    SKINSERVE_CL_ERROR(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    SKINSERVE_CL_ERROR(CL_INVALID_IMAGE_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_SAMPLER)
    SKINSERVE_CL_ERROR(CL_INVALID_BINARY)
    SKINSERVE_CL_ERROR(CL_INVALID_BUILD_OPTIONS)
    SKINSERVE_CL_ERROR(CL_INVALID_PROGRAM)
    SKINSERVE_CL_ERROR(CL_INVALID_PROGRAM_EXECUTABLE)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL_NAME)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL_DEFINITION)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_INDEX)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_VALUE)
    SKINSERVE_CL_ERROR(CL_INVALID_ARG_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_KERNEL_ARGS)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_DIMENSION)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_GROUP_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_WORK_ITEM_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_GLOBAL_OFFSET)
    SKINSERVE_CL_ERROR(CL_INVALID_EVENT_WAIT_LIST)
    SKINSERVE_CL_ERROR(CL_INVALID_EVENT)
    SKINSERVE_CL_ERROR(CL_INVALID_OPERATION)
    SKINSERVE_CL_ERROR(CL_INVALID_GL_OBJECT)
    SKINSERVE_CL_ERROR(CL_INVALID_BUFFER_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_MIP_LEVEL)
    SKINSERVE_CL_ERROR(CL_INVALID_GLOBAL_WORK_SIZE)
    SKINSERVE_CL_ERROR(CL_INVALID_PROPERTY)
    SKINSERVE_CL_ERROR(CL_INVALID_IMAGE_DESCRIPTOR)
    SKINSERVE_CL_ERROR(CL_INVALID_COMPILER_OPTIONS)
    SKINSERVE_CL_ERROR(CL_INVALID_LINKER_OPTIONS)
    SKINSERVE_CL_ERROR(CL_INVALID_DEVICE_PARTITION_COUNT)
#undef SKINSERVE_CL_ERROR
    case kPlatformNotFoundKhr:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "CL_UNKNOWN_ERROR";
  }
}

Status ClError(const char* call, cl_int code) {
  std::string message = fmt::format("{} failed: {} ({})", call, ClErrorName(code), code);
  const bool out_of_memory = code == CL_OUT_OF_HOST_MEMORY || code == CL_OUT_OF_RESOURCES ||
                             code == CL_MEM_OBJECT_ALLOCATION_FAILURE;
  return out_of_memory ? ResourceExhausted(std::move(message)) : Internal(std::move(message));
}

Result<std::shared_ptr<OpenClRuntime>> OpenClRuntime::Create(int threads) {
  // PoCL sizes its worker pool when the ICD loader first loads it, i.e. on the first
  // clGetPlatformIDs of the process: match the engine's compute threads, unless the
  // operator chose otherwise. (Called while the engine is built, before its threads run.)
  setenv("POCL_MAX_PTHREAD_COUNT", std::to_string(std::max(threads, 1)).c_str(),
         /*overwrite=*/0);
  auto picked = PickDevice();
  if (!picked.ok()) return picked.status();

  std::shared_ptr<OpenClRuntime> runtime(new OpenClRuntime());
  runtime->device_ = picked->device;
  auto name = DeviceString(picked->device, CL_DEVICE_NAME, "clGetDeviceInfo(CL_DEVICE_NAME)");
  if (!name.ok()) return name.status();
  runtime->device_name_ = *name;
  auto version = PlatformString(picked->platform, CL_PLATFORM_VERSION,
                                "clGetPlatformInfo(CL_PLATFORM_VERSION)");
  if (!version.ok()) return version.status();
  runtime->platform_version_ = ShortVersion(*version);
  cl_uint units = 1, width = 1;
  if (Status s = DeviceUint(picked->device, CL_DEVICE_MAX_COMPUTE_UNITS,
                            "clGetDeviceInfo(CL_DEVICE_MAX_COMPUTE_UNITS)", &units);
      !s.ok()) {
    return s;
  }
  if (Status s = DeviceUint(picked->device, CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT,
                            "clGetDeviceInfo(CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT)", &width);
      !s.ok()) {
    return s;
  }
  runtime->compute_units_ = static_cast<int>(units);
  runtime->vector_width_ = static_cast<int>(width);

  cl_int err = CL_SUCCESS;
  runtime->context_ = clCreateContext(nullptr, 1, &runtime->device_, nullptr, nullptr, &err);
  if (err != CL_SUCCESS) return ClError("clCreateContext", err);
  runtime->queue_ = clCreateCommandQueue(runtime->context_, runtime->device_, 0, &err);
  if (err != CL_SUCCESS) return ClError("clCreateCommandQueue", err);
  if (Status s = runtime->Build(); !s.ok()) return s;
  if (Status s = runtime->Warm(); !s.ok()) return s;
  return runtime;
}

Status OpenClRuntime::Build() {
  const char* source = kernels::kLinearBlendSkinningSource.data();
  const std::size_t length = kernels::kLinearBlendSkinningSource.size();
  cl_int err = CL_SUCCESS;
  program_ = clCreateProgramWithSource(context_, 1, &source, &length, &err);
  if (err != CL_SUCCESS) return ClError("clCreateProgramWithSource", err);
  const std::string options =
      fmt::format("-cl-std=CL1.2 -DSKIN_VERTICES_PER_ITEM={}", kVerticesPerItem);
  err = clBuildProgram(program_, 1, &device_, options.c_str(), nullptr, nullptr);
  if (err != CL_SUCCESS) {
    std::size_t log_size = 0;
    std::string log;
    cl_int log_err =
        clGetProgramBuildInfo(program_, device_, CL_PROGRAM_BUILD_LOG, 0, nullptr, &log_size);
    if (log_err == CL_SUCCESS) {
      log.resize(log_size);
      log_err = clGetProgramBuildInfo(program_, device_, CL_PROGRAM_BUILD_LOG, log_size, log.data(),
                                      nullptr);
    }
    if (log_err != CL_SUCCESS) {
      log = fmt::format("(no log: clGetProgramBuildInfo failed: {} ({}))", ClErrorName(log_err),
                        log_err);
    }
    while (!log.empty() && log.back() == '\0') log.pop_back();
    return FailedPrecondition(
        fmt::format("clBuildProgram failed: {} ({}); build log:\n{}", ClErrorName(err), err, log));
  }
  for (std::size_t normals = 0; normals < 2; ++normals) {
    for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
      const std::string name = fmt::format("{}{}", normals ? "skin_normals_b" : "skin_b", b);
      cl_kernel kernel = clCreateKernel(program_, name.c_str(), &err);
      if (err != CL_SUCCESS) return ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
      kernels_[normals][b - 1] = kernel;
    }
  }
  return Status::Ok();
}

OpenClRuntime::~OpenClRuntime() {
  for (auto& row : kernels_) {
    for (cl_kernel kernel : row) {
      if (kernel != nullptr) clReleaseKernel(kernel);
    }
  }
  if (program_ != nullptr) clReleaseProgram(program_);
  if (queue_ != nullptr) clReleaseCommandQueue(queue_);
  if (context_ != nullptr) clReleaseContext(context_);
}

Result<ClBuffer> OpenClRuntime::CreateBuffer(const char* what, cl_mem_flags flags,
                                             std::size_t bytes, const void* host) {
  cl_int err = CL_SUCCESS;
  // OpenCL takes a non-const host pointer even for read-only buffers.
  cl_mem mem = clCreateBuffer(context_, flags, bytes, const_cast<void*>(host), &err);
  if (err != CL_SUCCESS) return ClError(fmt::format("clCreateBuffer({})", what).c_str(), err);
  return ClBuffer(mem);
}

Status OpenClRuntime::EnqueueSkin(const Mesh& mesh, const SkinKernelArgs& args) {
  const uint32_t influences = mesh.influences();
  if (influences < 1 || influences > kMaxInfluences) {
    return Internal(fmt::format("no OpenCL kernel for {} influences", influences));
  }
  const cl_uint count = mesh.vertex_count();
  if (count == 0) return Status::Ok();
  const bool with_normals = args.out_normals != nullptr;
  if (with_normals && args.normals == nullptr) {
    return Internal("output normals without input normals: the mesh has none");
  }
  cl_kernel kernel = kernels_[with_normals ? 1 : 0][influences - 1];
  // Argument order: see SKIN_ARGS in kernels/linear_blend_skinning.cl.
  const cl_mem buffers[] = {args.palette, args.joints, args.weights, args.positions,
                            args.out_positions};
  cl_uint index = 0;
  for (const cl_mem& buffer : buffers) {
    if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_mem), &buffer); err != CL_SUCCESS) {
      return ClError("clSetKernelArg", err);
    }
  }
  if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_uint), &count); err != CL_SUCCESS) {
    return ClError("clSetKernelArg(vertex_count)", err);
  }
  if (with_normals) {
    for (const cl_mem* buffer : {&args.normals, &args.out_normals}) {
      if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_mem), buffer); err != CL_SUCCESS) {
        return ClError("clSetKernelArg(normals)", err);
      }
    }
  }
  const std::size_t items = (count + kVerticesPerItem - 1) / kVerticesPerItem;
  const std::size_t local = kItemsPerGroup;
  const std::size_t global = (items + local - 1) / local * local;
  if (cl_int err =
          clEnqueueNDRangeKernel(queue_, kernel, 1, nullptr, &global, &local, 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel", err);
  }
  return Status::Ok();
}

// PoCL compiles a kernel's work-group function on its first launch (per work-group
// size): do that now, for every kernel, so no client's first frame pays for it.
Status OpenClRuntime::Warm() {
  MeshArrays arrays{.vertex_count = 1,
                    .influences = kMaxInfluences,
                    .joint_count = 1,
                    .positions = {0, 0, 0},
                    .normals = {0, 0, 1},
                    .joints = std::vector<uint16_t>(kMaxInfluences, 0),
                    .weights = std::vector<float>(kMaxInfluences, 1.0f / kMaxInfluences)};
  const std::vector<float> palette = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  constexpr cl_mem_flags kIn = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
  auto pal = CreateBuffer("warm palette", kIn, palette.size() * sizeof(float), palette.data());
  auto pos = CreateBuffer("warm positions", kIn, 3 * sizeof(float), arrays.positions.data());
  auto nrm = CreateBuffer("warm normals", kIn, 3 * sizeof(float), arrays.normals.data());
  auto jnt =
      CreateBuffer("warm joints", kIn, kMaxInfluences * sizeof(uint16_t), arrays.joints.data());
  auto wgt =
      CreateBuffer("warm weights", kIn, kMaxInfluences * sizeof(float), arrays.weights.data());
  auto out = CreateBuffer("warm output", CL_MEM_WRITE_ONLY, 3 * sizeof(float), nullptr);
  auto out_n = CreateBuffer("warm output", CL_MEM_WRITE_ONLY, 3 * sizeof(float), nullptr);
  for (const auto* r : {&pal, &pos, &nrm, &jnt, &wgt, &out, &out_n}) {
    if (!r->ok()) return r->status();
  }
  // Each B needs its own mesh shape; the buffers above are large enough for every B.
  for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
    arrays.influences = b;
    arrays.joints.assign(b, 0);
    arrays.weights.assign(b, 1.0f / static_cast<float>(b));
    auto mesh = Mesh::Create(arrays);
    if (!mesh.ok()) return mesh.status();
    SkinKernelArgs args{pal->get(), jnt->get(), wgt->get(), pos->get(), out->get()};
    if (Status s = EnqueueSkin(**mesh, args); !s.ok()) return s;
    args.normals = nrm->get();
    args.out_normals = out_n->get();
    if (Status s = EnqueueSkin(**mesh, args); !s.ok()) return s;
  }
  if (cl_int err = clFinish(queue_); err != CL_SUCCESS) return ClError("clFinish(warm-up)", err);
  return Status::Ok();
}

}  // namespace skinserve
