#include "backends/opencl/opencl_runtime.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "backends/opencl/opencl_program.h"
#include "backends/opencl/opencl_quantized.h"
#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {
namespace {

// Vertices one work-item skins; the kernel checks it gets the value it is written for.
constexpr std::size_t kVerticesPerItem = 4;
// Work-items per work-group (256 vertices): past 64, PoCL's per-group cost is noise; on
// a GPU, two warps.
constexpr std::size_t kItemsPerGroup = 64;
static_assert(kVerticesPerItem * kItemsPerGroup == OpenClRuntime::kChunkAlignment);
// The morph kernels (morph_targets.cl): vertices per work-item (each item searches each
// active target once: 256 keeps the searches a small part of the work, see the kernel, and
// still gives 25k vertices 13 work-groups), and items per work-group, one fixed size so
// that PoCL compiles the kernel once, at warm-up.
constexpr uint32_t kMorphVerticesPerItem = 256;
constexpr std::size_t kMorphItemsPerGroup = 8;
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

template <typename T>
Status DeviceUint(cl_device_id device, cl_device_info what, const char* name, T* value) {
  if (cl_int err = clGetDeviceInfo(device, what, sizeof(*value), value, nullptr);
      err != CL_SUCCESS) {
    return ClError(name, err);
  }
  return Status::Ok();
}

std::string Lower(std::string s) {
  for (char& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

struct DeviceEntry {
  cl_platform_id platform = nullptr;
  cl_device_id device = nullptr;
  std::string platform_name, device_name;
  cl_device_type type = 0;
};

std::string TypeName(cl_device_type type) {
  if (type & CL_DEVICE_TYPE_CPU) return "CPU";
  if (type & CL_DEVICE_TYPE_GPU) return "GPU";
  if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  return "other";
}

// Every device of every platform, in the ICD loader's order.
Result<std::vector<DeviceEntry>> ListDevices() {
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
  std::vector<DeviceEntry> entries;
  std::string failures;
  for (cl_platform_id platform : platforms) {
    auto platform_name =
        PlatformString(platform, CL_PLATFORM_NAME, "clGetPlatformInfo(CL_PLATFORM_NAME)");
    if (!platform_name.ok()) return platform_name.status();
    cl_uint device_count = 0;
    err = clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 0, nullptr, &device_count);
    if (err != CL_SUCCESS || device_count == 0) {
      failures += fmt::format("; platform '{}': clGetDeviceIDs: {} ({})", *platform_name,
                              ClErrorName(err), err);
      continue;
    }
    std::vector<cl_device_id> devices(device_count);
    if (err = clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, device_count, devices.data(), nullptr);
        err != CL_SUCCESS) {
      return ClError("clGetDeviceIDs", err);
    }
    for (cl_device_id device : devices) {
      DeviceEntry entry{platform, device, *platform_name, "", 0};
      auto name = DeviceString(device, CL_DEVICE_NAME, "clGetDeviceInfo(CL_DEVICE_NAME)");
      if (!name.ok()) return name.status();
      entry.device_name = *name;
      if (err = clGetDeviceInfo(device, CL_DEVICE_TYPE, sizeof(entry.type), &entry.type, nullptr);
          err != CL_SUCCESS) {
        return ClError("clGetDeviceInfo(CL_DEVICE_TYPE)", err);
      }
      entries.push_back(std::move(entry));
    }
  }
  if (entries.empty()) {
    return FailedPrecondition(
        fmt::format("no OpenCL device found on {} platform(s){}", platform_count, failures));
  }
  return entries;
}

// See OpenClRuntimeOptions::device.
Result<DeviceEntry> PickDevice(const std::string& choice) {
  auto entries = ListDevices();
  if (!entries.ok()) return entries.status();
  const std::string wanted = Lower(choice);
  auto matches = [&](const DeviceEntry& e) {
    if (wanted == "cpu") return (e.type & CL_DEVICE_TYPE_CPU) != 0;
    if (wanted == "gpu") return (e.type & CL_DEVICE_TYPE_GPU) != 0;
    return Lower(e.platform_name).find(wanted) != std::string::npos ||
           Lower(e.device_name).find(wanted) != std::string::npos;
  };
  if (wanted.empty()) {
    for (const DeviceEntry& e : *entries) {
      if (e.type & CL_DEVICE_TYPE_CPU) return e;
    }
    return entries->front();
  }
  for (const DeviceEntry& e : *entries) {
    if (matches(e)) return e;
  }
  std::string found;
  for (const DeviceEntry& e : *entries) {
    found += fmt::format("{}platform '{}': device '{}' ({})", found.empty() ? "" : "; ",
                         e.platform_name, e.device_name, TypeName(e.type));
  }
  return FailedPrecondition(fmt::format(
      "OpenCL device choice '{}' (cpu, gpu, or part of a platform or device name) matches no "
      "device; found: {}",
      choice, found));
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

Result<int64_t> ProfiledNs(const std::vector<cl_event>& events) {
  int64_t total = 0;
  for (cl_event event : events) {
    cl_ulong start = 0, end = 0;
    cl_int err =
        clGetEventProfilingInfo(event, CL_PROFILING_COMMAND_START, sizeof(start), &start, nullptr);
    if (err == CL_SUCCESS) {
      err = clGetEventProfilingInfo(event, CL_PROFILING_COMMAND_END, sizeof(end), &end, nullptr);
    }
    if (err != CL_SUCCESS) return ClError("clGetEventProfilingInfo", err);
    total += static_cast<int64_t>(end - start);
  }
  return total;
}

Status RecordDeviceTiming(const ClEvents& kernels, const ClEvents& transfers, bool profiled,
                          DeviceTiming* timing) {
  if (timing == nullptr || !profiled) return Status::Ok();
  auto kernel_ns = ProfiledNs(kernels.all());
  if (!kernel_ns.ok()) return kernel_ns.status();
  auto transfer_ns = ProfiledNs(transfers.all());
  if (!transfer_ns.ok()) return transfer_ns.status();
  *timing = {.transfer_ns = *transfer_ns, .kernel_ns = *kernel_ns};
  return Status::Ok();
}

Result<std::shared_ptr<OpenClRuntime>> OpenClRuntime::Create(const OpenClRuntimeOptions& options) {
  // PoCL sizes its worker pool when the ICD loader first loads it, i.e. on the first
  // clGetPlatformIDs of the process: match the engine's compute threads, unless the
  // operator chose otherwise. (Called while the engine is built, before its threads run.)
  const int threads = std::max(options.threads, 1);
  setenv("POCL_MAX_PTHREAD_COUNT", std::to_string(threads).c_str(), /*overwrite=*/0);
  auto picked = PickDevice(options.device);
  if (!picked.ok()) return picked.status();

  std::shared_ptr<OpenClRuntime> runtime(new OpenClRuntime());
  runtime->device_ = picked->device;
  runtime->device_name_ = picked->device_name;
  runtime->is_cpu_ = (picked->type & CL_DEVICE_TYPE_CPU) != 0;
  auto version = PlatformString(picked->platform, CL_PLATFORM_VERSION,
                                "clGetPlatformInfo(CL_PLATFORM_VERSION)");
  if (!version.ok()) return version.status();
  runtime->platform_version_ = ShortVersion(*version);
  if (Status s = runtime->ReadDeviceShape(options); !s.ok()) return s;
  if (Status s = runtime->BuildPrograms(); !s.ok()) return s;
  const int lanes = options.lanes > 0 ? options.lanes : (runtime->staging_ ? 4 : 1);
  runtime->threads_ = threads;
  runtime->SetChunks(options);
  if (Status s = runtime->CreateLanes(lanes); !s.ok()) return s;
  if (runtime->local_palette()) {
    if (Status s = runtime->FitLocalPalette(options); !s.ok()) return s;
  }
  if (Status s = runtime->Warm(); !s.ok()) return s;
  return runtime;
}

// The device's compute units and vector width, and what follows from its type and
// `options`: staging, the coalesced order, local memory for the palette, the local tiles.
Status OpenClRuntime::ReadDeviceShape(const OpenClRuntimeOptions& options) {
  cl_uint units = 1, width = 1;
  if (Status s = DeviceUint(device_, CL_DEVICE_MAX_COMPUTE_UNITS,
                            "clGetDeviceInfo(CL_DEVICE_MAX_COMPUTE_UNITS)", &units);
      !s.ok()) {
    return s;
  }
  if (Status s = DeviceUint(device_, CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT,
                            "clGetDeviceInfo(CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT)", &width);
      !s.ok()) {
    return s;
  }
  cl_uint align_bits = 0;
  if (Status s = DeviceUint(device_, CL_DEVICE_MEM_BASE_ADDR_ALIGN,
                            "clGetDeviceInfo(CL_DEVICE_MEM_BASE_ADDR_ALIGN)", &align_bits);
      !s.ok()) {
    return s;
  }
  compute_units_ = static_cast<int>(units);
  vector_width_ = static_cast<int>(width);
  base_address_alignment_ = std::max<uint64_t>(align_bits / 8, 1);
  staging_ = !is_cpu_ || options.force_staging;
  device_timing_ = options.device_timing;
  mesh_arena_bytes_ = options.mesh_arena_bytes;
  const char* tick_launches = std::getenv("SKINSERVE_OPENCL_TICK_LAUNCHES");
  tick_launches_ =
      options.tick_launches && (tick_launches == nullptr || std::string(tick_launches) != "0");
  coalesced_ = !is_cpu_ || options.force_coalesced;
  // The local-palette kernels: on the coalesced path, unless turned off, up to the
  // device's local memory, less what the kernels use themselves, and at most the caller's
  // limit (both applied once the kernels exist: FitLocalPalette).
  if (coalesced_ && options.local_palette == OpenClRuntimeOptions::LocalPalette::kAuto) {
    cl_ulong local_bytes = 0;
    if (Status s = DeviceUint(device_, CL_DEVICE_LOCAL_MEM_SIZE,
                              "clGetDeviceInfo(CL_DEVICE_LOCAL_MEM_SIZE)", &local_bytes);
        !s.ok()) {
      return s;
    }
    local_palette_bytes_ = static_cast<std::size_t>(local_bytes);
  }
  local_tiles_ = options.local_tiles;
  if (const char* tiles = std::getenv("SKINSERVE_OPENCL_LOCAL_TILES");
      local_tiles_ <= 0 && tiles != nullptr) {
    local_tiles_ = std::atoi(tiles);
  }
  if (local_tiles_ <= 0) local_tiles_ = kDefaultLocalTiles;
  return Status::Ok();
}

// The context, the skinning program and the quantized kernels' builder, for the shape
// ReadDeviceShape found.
Status OpenClRuntime::BuildPrograms() {
  cl_int err = CL_SUCCESS;
  context_ = clCreateContext(nullptr, 1, &device_, nullptr, nullptr, &err);
  if (err != CL_SUCCESS) return ClError("clCreateContext", err);
  // On a GPU, consecutive work-items take consecutive vertices (coalesced loads and
  // stores), and the *_local_* kernels stage the palette in local memory; on a CPU, each
  // work-item takes four consecutive vertices (see the kernel).
  const std::string build_options = fmt::format(
      "-cl-std=CL1.2 -DSKIN_VERTICES_PER_ITEM={} -DSKIN_ITEMS_PER_GROUP={} "
      "-DSKIN_COALESCED={} -DSKIN_LOCAL_PALETTE={} -DSKIN_LOCAL_TILES={} "
      "-DMORPH_VERTICES_PER_ITEM={}",
      kVerticesPerItem, kItemsPerGroup, coalesced_ ? 1 : 0, local_palette() ? 1 : 0, local_tiles_,
      kMorphVerticesPerItem);
  if (Status s = Build(build_options); !s.ok()) return s;
  quantized_ =
      std::make_unique<OpenClQuantizedKernels>(context_, device_, build_options, local_tiles_);
  return Status::Ok();
}

void OpenClRuntime::SetChunks(const OpenClRuntimeOptions& options) {
  max_chunks_ = options.max_chunks;
  if (const char* chunks = std::getenv("SKINSERVE_OPENCL_CHUNKS");
      max_chunks_ <= 0 && chunks != nullptr) {
    max_chunks_ = std::atoi(chunks);
  }
  if (max_chunks_ <= 0) max_chunks_ = kDefaultChunks;
  min_chunk_vertices_ = std::max<uint32_t>(options.min_chunk_vertices, 1) + kChunkAlignment - 1;
  min_chunk_vertices_ -= min_chunk_vertices_ % kChunkAlignment;
}

// What the local kernels use of local memory themselves (the staged palette, their one
// __local argument, counts as 0 until set) is not the palette's; then the caller's limit.
Status OpenClRuntime::FitLocalPalette(const OpenClRuntimeOptions& options) {
  cl_ulong own = 0;
  for (const auto& method : lanes_.front()->kernels[1]) {
    for (const auto& row : method) {
      for (cl_kernel kernel : row) {
        cl_ulong bytes = 0;
        if (cl_int info_err = clGetKernelWorkGroupInfo(kernel, device_, CL_KERNEL_LOCAL_MEM_SIZE,
                                                       sizeof(bytes), &bytes, nullptr);
            info_err != CL_SUCCESS) {
          return ClError("clGetKernelWorkGroupInfo(CL_KERNEL_LOCAL_MEM_SIZE)", info_err);
        }
        own = std::max(own, bytes);
      }
    }
  }
  local_palette_bytes_ -= std::min<std::size_t>(local_palette_bytes_, own);
  if (options.local_palette_max_bytes > 0) {
    local_palette_bytes_ = std::min(local_palette_bytes_, options.local_palette_max_bytes);
  }
  return Status::Ok();
}

Status OpenClRuntime::Build(const std::string& options) {
  // One program: the dual-quaternion kernels use the linear file's arguments, the tick
  // kernels its blend and stores.
  const std::string_view sources[] = {kernels::kLinearBlendSkinningSource,
                                      kernels::kDualQuaternionSkinningSource,
                                      kernels::kMorphTargetsSource, kernels::kTickSkinningSource};
  auto program = BuildSkinningProgram(context_, device_, sources, options, "skinning");
  if (!program.ok()) return program.status();
  program_ = *program;
  return Status::Ok();
}

Status OpenClRuntime::CreateLanes(int count) {
  for (int i = 0; i < count; ++i) {
    auto lane = std::make_unique<OpenClLane>();
    cl_int err = CL_SUCCESS;
    // Profiled only when frames report their device time (OpenClRuntimeOptions).
    const cl_command_queue_properties properties = device_timing_ ? CL_QUEUE_PROFILING_ENABLE : 0;
    lane->compute = clCreateCommandQueue(context_, device_, properties, &err);
    if (err != CL_SUCCESS) return ClError("clCreateCommandQueue", err);
    if (staging_) {
      lane->transfer = clCreateCommandQueue(context_, device_, properties, &err);
      if (err != CL_SUCCESS) return ClError("clCreateCommandQueue(transfer)", err);
    } else {
      lane->transfer = lane->compute;
      clRetainCommandQueue(lane->transfer);
    }
    // Linear blending (linear_blend_skinning.cl), then dual quaternions
    // (dual_quaternion_skinning.cl), each for positions, with normals, with normals and
    // tangents. With the local palette, their *_local_* variants too.
    constexpr const char* kPrefixes[2][2][3] = {
        {{"skin_b", "skin_normals_b", "skin_tangents_b"},
         {"dqs_b", "dqs_normals_b", "dqs_tangents_b"}},
        {{"skin_local_b", "skin_normals_local_b", "skin_tangents_local_b"},
         {"dqs_local_b", "dqs_normals_local_b", "dqs_tangents_local_b"}}};
    for (std::size_t local = 0; local < (local_palette() ? 2 : 1); ++local) {
      for (std::size_t method = 0; method < 2; ++method) {
        for (std::size_t outputs = 0; outputs < 3; ++outputs) {
          for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
            const std::string name = fmt::format("{}{}", kPrefixes[local][method][outputs], b);
            cl_kernel kernel = clCreateKernel(program_, name.c_str(), &err);
            if (err != CL_SUCCESS) {
              return ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
            }
            lane->kernels[local][method][outputs][b - 1] = kernel;
          }
        }
      }
    }
    // Tick launches (tick_skinning.cl), [local][outputs][B - 1].
    constexpr const char* kTickPrefixes[2][3] = {
        {"tick_b", "tick_normals_b", "tick_tangents_b"},
        {"tick_local_b", "tick_normals_local_b", "tick_tangents_local_b"}};
    for (std::size_t local = 0; local < (local_palette() ? 2 : 1); ++local) {
      for (std::size_t outputs = 0; outputs < 3; ++outputs) {
        for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
          const std::string name = fmt::format("{}{}", kTickPrefixes[local][outputs], b);
          cl_kernel kernel = clCreateKernel(program_, name.c_str(), &err);
          if (err != CL_SUCCESS) {
            return ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
          }
          lane->tick_kernels[local][outputs][b - 1] = kernel;
        }
      }
    }
    // Morph targets (morph_targets.cl), [with normals][with tangents].
    constexpr const char* kMorphNames[2][2] = {
        {"morph_positions", "morph_positions_tangents"},
        {"morph_positions_normals", "morph_positions_normals_tangents"}};
    for (std::size_t normals = 0; normals < 2; ++normals) {
      for (std::size_t tangents = 0; tangents < 2; ++tangents) {
        const char* name = kMorphNames[normals][tangents];
        lane->morph_kernels[normals][tangents] = clCreateKernel(program_, name, &err);
        if (err != CL_SUCCESS) return ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
      }
    }
    free_lanes_.push_back(lane.get());
    lanes_.push_back(std::move(lane));
  }
  return Status::Ok();
}

OpenClRuntime::~OpenClRuntime() {
  quantized_.reset();  // its kernels and programs before the context
  for (auto& lane : lanes_) {
    for (auto& variant : lane->kernels) {
      for (auto& method : variant) {
        for (auto& row : method) {
          for (cl_kernel kernel : row) {
            if (kernel != nullptr) clReleaseKernel(kernel);
          }
        }
      }
    }
    for (const auto& row : lane->morph_kernels) {
      for (cl_kernel kernel : row) {
        if (kernel != nullptr) clReleaseKernel(kernel);
      }
    }
    for (const auto& variant : lane->tick_kernels) {
      for (const auto& row : variant) {
        for (cl_kernel kernel : row) {
          if (kernel != nullptr) clReleaseKernel(kernel);
        }
      }
    }
    // Unmapped before release: the buffers' destructors release them afterwards.
    for (PinnedBuffer* pinned :
         {&lane->pinned_palette, &lane->pinned_positions, &lane->pinned_normals,
          &lane->pinned_tangents, &lane->pinned_batch_palettes, &lane->pinned_batch_outputs,
          &lane->pinned_tick_palettes}) {
      if (pinned->host != nullptr) {
        clEnqueueUnmapMemObject(lane->compute, pinned->buffer.get(), pinned->host, 0, nullptr,
                                nullptr);
      }
    }
    if (lane->compute != nullptr) clFinish(lane->compute);
    if (lane->transfer != nullptr) clReleaseCommandQueue(lane->transfer);
    if (lane->compute != nullptr) clReleaseCommandQueue(lane->compute);
  }
  lanes_.clear();
  if (program_ != nullptr) clReleaseProgram(program_);
  if (context_ != nullptr) clReleaseContext(context_);
}

OpenClRuntime::Lease OpenClRuntime::AcquireLane() {
  std::unique_lock lock(lanes_mutex_);
  lane_freed_.wait(lock, [this] { return !free_lanes_.empty(); });
  OpenClLane* lane = free_lanes_.back();
  free_lanes_.pop_back();
  return Lease(this, lane, static_cast<int>(lanes_.size() - free_lanes_.size()));
}

void OpenClRuntime::Release(OpenClLane* lane) {
  {
    std::lock_guard lock(lanes_mutex_);
    free_lanes_.push_back(lane);
  }
  lane_freed_.notify_one();
}

Result<ClBuffer> OpenClRuntime::CreateBuffer(const char* what, cl_mem_flags flags,
                                             std::size_t bytes, const void* host) {
  cl_int err = CL_SUCCESS;
  // OpenCL takes a non-const host pointer even for read-only buffers.
  cl_mem mem = clCreateBuffer(context_, flags, bytes, const_cast<void*>(host), &err);
  if (err != CL_SUCCESS) return ClError(fmt::format("clCreateBuffer({})", what).c_str(), err);
  return ClBuffer(mem);
}

namespace {
// Buffers grow in steps of this, so a slowly growing mesh does not reallocate every frame.
constexpr std::size_t kGrowStep = 1u << 20;
std::size_t RoundUp(std::size_t bytes) { return (bytes + kGrowStep - 1) / kGrowStep * kGrowStep; }
}  // namespace

Status OpenClRuntime::GrowBuffer(const char* what, cl_mem_flags flags, std::size_t bytes,
                                 ClBuffer* buffer, std::size_t* capacity) {
  if (buffer->get() != nullptr && *capacity >= bytes) return Status::Ok();
  *buffer = ClBuffer();
  *capacity = 0;
  auto created = CreateBuffer(what, flags, RoundUp(bytes), nullptr);
  if (!created.ok()) return created.status();
  *buffer = std::move(created).value();
  *capacity = RoundUp(bytes);
  return Status::Ok();
}

Status OpenClRuntime::GrowPinned(cl_command_queue queue, const char* what, std::size_t bytes,
                                 PinnedBuffer* pinned) {
  if (pinned->host != nullptr && pinned->bytes >= bytes) return Status::Ok();
  if (pinned->host != nullptr) {
    cl_int err =
        clEnqueueUnmapMemObject(queue, pinned->buffer.get(), pinned->host, 0, nullptr, nullptr);
    if (err == CL_SUCCESS) err = clFinish(queue);
    if (err != CL_SUCCESS)
      return ClError(fmt::format("clEnqueueUnmapMemObject({})", what).c_str(), err);
  }
  *pinned = PinnedBuffer();
  const std::size_t size = RoundUp(bytes);
  auto buffer = CreateBuffer(what, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, size, nullptr);
  if (!buffer.ok()) return buffer.status();
  cl_int err = CL_SUCCESS;
  void* host = clEnqueueMapBuffer(queue, buffer->get(), CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0,
                                  size, 0, nullptr, nullptr, &err);
  if (err != CL_SUCCESS) {
    return ClError(fmt::format("clEnqueueMapBuffer({})", what).c_str(), err);
  }
  pinned->buffer = std::move(buffer).value();
  pinned->host = host;
  pinned->bytes = size;
  return Status::Ok();
}

namespace {
// Floats per joint of the palette the kernels read: the 3x4 matrix, or the dual quaternion.
std::size_t PaletteFloatsPerJoint(SkinningMethod method) {
  return method == SkinningMethod::kDualQuaternion ? 8 : 12;
}
}  // namespace

bool OpenClRuntime::UsesLocalPalette(const Mesh& mesh, SkinningMethod method) const {
  const std::size_t bytes = mesh.joint_count() * PaletteFloatsPerJoint(method) * sizeof(float);
  return local_palette() && bytes > 0 && bytes <= local_palette_bytes_;
}

Status OpenClRuntime::EnqueueSkin(OpenClLane& lane, const Mesh& mesh, const SkinKernelArgs& args,
                                  uint32_t first, uint32_t end, cl_event* event) {
  if (mesh.quantized_rest() != nullptr) {
    return quantized_->Enqueue(lane, mesh, args, first, end, UsesLocalPalette(mesh, args.method),
                               event);
  }
  return EnqueueSkinKernel(lane, mesh, args, first, end, UsesLocalPalette(mesh, args.method),
                           event);
}

Status OpenClRuntime::EnqueueSkinKernel(OpenClLane& lane, const Mesh& mesh,
                                        const SkinKernelArgs& args, uint32_t first, uint32_t end,
                                        bool local, cl_event* event) {
  const uint32_t influences = mesh.influences();
  if (influences < 1 || influences > kMaxInfluences) {
    return Internal(fmt::format("no OpenCL kernel for {} influences", influences));
  }
  if (first % kChunkAlignment != 0 || end > mesh.vertex_count() || first > end) {
    return Internal(
        fmt::format("bad vertex range [{}, {}) of {}", first, end, mesh.vertex_count()));
  }
  if (first == end) return Status::Ok();
  const bool with_normals = args.out_normals != nullptr;
  if (with_normals && args.normals == nullptr) {
    return Internal("output normals without input normals: the mesh has none");
  }
  const bool with_tangents = args.out_tangents != nullptr;
  if (with_tangents && (args.tangents == nullptr || !with_normals)) {
    return Internal("output tangents without input tangents or without normals");
  }
  const bool dual_quaternion = args.method == SkinningMethod::kDualQuaternion;
  const int outputs = with_tangents ? 2 : (with_normals ? 1 : 0);
  cl_kernel kernel = lane.kernels[local ? 1 : 0][dual_quaternion ? 1 : 0][outputs][influences - 1];
  if (kernel == nullptr) return Internal("the local-palette kernels are not built");
  // Argument order: see SKIN_ARGS in kernels/linear_blend_skinning.cl (the
  // dual-quaternion kernels take the same). The kernel's
  // vertex_count is the range's end: it clamps to end - 1, and never reads past it.
  const cl_mem buffers[] = {args.palette, args.joints, args.weights, args.positions,
                            args.out_positions};
  const cl_uint count = end;
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
  if (with_tangents) {  // SKIN_TANGENT_ARGS: after the normals
    for (const cl_mem* buffer : {&args.tangents, &args.out_tangents}) {
      if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_mem), buffer); err != CL_SUCCESS) {
        return ClError("clSetKernelArg(tangents)", err);
      }
    }
  }
  // The local kernels: the staged palette (its size is the argument's, no buffer) and its
  // float count, after every other argument.
  if (local) {
    const cl_uint floats =
        static_cast<cl_uint>(mesh.joint_count() * PaletteFloatsPerJoint(args.method));
    if (cl_int err = clSetKernelArg(kernel, index++, floats * sizeof(float), nullptr);
        err != CL_SUCCESS) {
      return ClError("clSetKernelArg(staged palette)", err);
    }
    if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_uint), &floats); err != CL_SUCCESS) {
      return ClError("clSetKernelArg(palette_floats)", err);
    }
  }
  const std::size_t offset = first / kVerticesPerItem;
  const std::size_t items = (end - first + kVerticesPerItem - 1) / kVerticesPerItem;
  const std::size_t group = kItemsPerGroup;
  // A local kernel's group skins local_tiles_ groups' worth of vertices.
  const std::size_t per_group = local ? group * static_cast<std::size_t>(local_tiles_) : group;
  const std::size_t global = (items + per_group - 1) / per_group * group;
  if (cl_int err = clEnqueueNDRangeKernel(lane.compute, kernel, 1, &offset, &global, &group, 0,
                                          nullptr, event);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel", err);
  }
  return Status::Ok();
}

Status OpenClRuntime::EnqueueTick(OpenClLane& lane, const TickLaunch& launch, cl_event* event) {
  if (launch.influences < 1 || launch.influences > kMaxInfluences || launch.outputs < 0 ||
      launch.outputs > 2) {
    return Internal(fmt::format("no tick kernel for {} influences, outputs {}", launch.influences,
                                launch.outputs));
  }
  if (launch.characters == 0 || launch.most_vertices == 0) return Status::Ok();
  cl_kernel kernel = lane.tick_kernels[launch.local ? 1 : 0][launch.outputs][launch.influences - 1];
  if (kernel == nullptr) return Internal("the local-palette tick kernels are not built");
  // Argument order: TICK_ARGS in kernels/tick_skinning.cl, then the local kernels' staging.
  const cl_mem buffers[] = {launch.arena, launch.table, launch.palettes, launch.out};
  cl_uint index = 0;
  for (const cl_mem& buffer : buffers) {
    if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_mem), &buffer); err != CL_SUCCESS) {
      return ClError("clSetKernelArg(tick)", err);
    }
  }
  if (cl_int err = clSetKernelArg(kernel, index++, sizeof(cl_uint), &launch.first_row);
      err != CL_SUCCESS) {
    return ClError("clSetKernelArg(tick first row)", err);
  }
  if (launch.local) {
    if (cl_int err = clSetKernelArg(kernel, index++, launch.staged_bytes, nullptr);
        err != CL_SUCCESS) {
      return ClError("clSetKernelArg(tick staged palette)", err);
    }
  }
  // Dimension 0 as a single frame of the largest mesh (EnqueueSkinKernel), dimension 1
  // the characters, one per work-group row.
  const std::size_t items = (launch.most_vertices + kVerticesPerItem - 1) / kVerticesPerItem;
  const std::size_t per_group =
      launch.local ? kItemsPerGroup * static_cast<std::size_t>(local_tiles_) : kItemsPerGroup;
  const std::size_t global[2] = {(items + per_group - 1) / per_group * kItemsPerGroup,
                                 launch.characters};
  const std::size_t group[2] = {kItemsPerGroup, 1};
  if (cl_int err = clEnqueueNDRangeKernel(lane.compute, kernel, 2, nullptr, global, group, 0,
                                          nullptr, event);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel(tick)", err);
  }
  return Status::Ok();
}

Status OpenClRuntime::EnqueueMorph(OpenClLane& lane, uint32_t vertex_count,
                                   const MorphKernelArgs& args, cl_event* event) {
  const bool with_normals = args.morphed_normals != nullptr;
  if (with_normals && (args.normals == nullptr || args.normal_deltas == nullptr)) {
    return Internal("morphed normals without the mesh's normals or normal deltas");
  }
  const bool with_tangents = args.morphed_tangents != nullptr;
  if (with_tangents && (args.tangents == nullptr || args.tangent_deltas == nullptr)) {
    return Internal("morphed tangents without the mesh's tangents or tangent deltas");
  }
  cl_kernel kernel = lane.morph_kernels[with_normals ? 1 : 0][with_tangents ? 1 : 0];
  // Argument order: see MORPH_ARGS in kernels/morph_targets.cl.
  cl_uint index = 0;
  auto set = [&](std::size_t size, const void* value) {
    return clSetKernelArg(kernel, index++, size, value);
  };
  cl_int err = CL_SUCCESS;
  for (const cl_mem* buffer :
       {&args.positions, &args.offsets, &args.indices, &args.position_deltas, &args.weights}) {
    if (err == CL_SUCCESS) err = set(sizeof(cl_mem), buffer);
  }
  if (err == CL_SUCCESS) err = set(sizeof(cl_uint), &args.weight_count);
  if (err == CL_SUCCESS) err = set(sizeof(cl_mem), &args.morphed_positions);
  const cl_uint count = vertex_count;
  if (err == CL_SUCCESS) err = set(sizeof(cl_uint), &count);
  if (with_normals) {
    for (const cl_mem* buffer : {&args.normals, &args.normal_deltas, &args.morphed_normals}) {
      if (err == CL_SUCCESS) err = set(sizeof(cl_mem), buffer);
    }
  }
  if (with_tangents) {  // MORPH_TANGENT_ARGS: after the normals' where they are
    for (const cl_mem* buffer : {&args.tangents, &args.tangent_deltas, &args.morphed_tangents}) {
      if (err == CL_SUCCESS) err = set(sizeof(cl_mem), buffer);
    }
  }
  if (err != CL_SUCCESS) return ClError("clSetKernelArg(morph)", err);
  const std::size_t items = (vertex_count + kMorphVerticesPerItem - 1) / kMorphVerticesPerItem;
  const std::size_t local = kMorphItemsPerGroup;
  const std::size_t global = (items + local - 1) / local * local;
  if (err = clEnqueueNDRangeKernel(lane.compute, kernel, 1, nullptr, &global, &local, 0, nullptr,
                                   event);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel(morph)", err);
  }
  return Status::Ok();
}

// PoCL compiles a kernel's work-group function on its first launch (per work-group
// size), other drivers finish their own work on first use: do that now, for every kernel
// on every lane, so no client's first frame pays for it.
// The warm-up's one-vertex mesh, palette, outputs and morph target on the device: large
// enough for every kernel, every B.
struct OpenClRuntime::WarmUpBuffers {
  ClBuffer palette, positions, normals, joints, weights, out, out_normals, tangents, out_tangents;
  ClBuffer tick_arena, tick_table, tick_out;
  ClBuffer morph_offsets, morph_indices, morph_deltas, morph_weights, morphed, morphed_normals,
      morphed_tangents;
};

Result<std::unique_ptr<OpenClRuntime::WarmUpBuffers>> OpenClRuntime::CreateWarmUpBuffers() {
  const float palette[] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  const float position[] = {0, 0, 0}, normal[] = {0, 0, 1}, tangent[] = {1, 0, 0, 1};
  const std::vector<uint16_t> joints(kMaxInfluences, 0);
  const std::vector<float> weights(kMaxInfluences, 1.0f / kMaxInfluences);
  // One target moving the vertex by zero, active with weight 1.
  const uint32_t morph_offsets[] = {0, 1}, morph_indices[] = {0};
  const float zero_delta[] = {0, 0, 0};
  const MorphWeight morph_weight[] = {{0, 1.0f}};
  constexpr cl_mem_flags kIn = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
  auto buffers = std::make_unique<WarmUpBuffers>();
  struct Plan {
    const char* what;
    ClBuffer* buffer;
    cl_mem_flags flags;
    std::size_t bytes;
    const void* host;
  };
  WarmUpBuffers& w = *buffers;
  const Plan plan[] = {
      {"warm palette", &w.palette, kIn, sizeof(palette), palette},
      {"warm positions", &w.positions, kIn, sizeof(position), position},
      {"warm normals", &w.normals, kIn, sizeof(normal), normal},
      {"warm joints", &w.joints, kIn, kMaxInfluences * sizeof(uint16_t), joints.data()},
      {"warm weights", &w.weights, kIn, kMaxInfluences * sizeof(float), weights.data()},
      {"warm output", &w.out, CL_MEM_WRITE_ONLY, sizeof(position), nullptr},
      {"warm output", &w.out_normals, CL_MEM_WRITE_ONLY, sizeof(normal), nullptr},
      {"warm tangents", &w.tangents, kIn, sizeof(tangent), tangent},
      {"warm output", &w.out_tangents, CL_MEM_WRITE_ONLY, sizeof(tangent), nullptr},
      {"warm morph offsets", &w.morph_offsets, kIn, sizeof(morph_offsets), morph_offsets},
      {"warm morph indices", &w.morph_indices, kIn, sizeof(morph_indices), morph_indices},
      {"warm morph deltas", &w.morph_deltas, kIn, sizeof(zero_delta), zero_delta},
      {"warm morph weights", &w.morph_weights, kIn, sizeof(morph_weight), morph_weight},
      {"warm morphed", &w.morphed, CL_MEM_READ_WRITE, sizeof(position), nullptr},
      {"warm morphed", &w.morphed_normals, CL_MEM_READ_WRITE, sizeof(normal), nullptr},
      {"warm morphed", &w.morphed_tangents, CL_MEM_READ_WRITE, sizeof(tangent), nullptr}};
  for (const Plan& p : plan) {
    auto buffer = CreateBuffer(p.what, p.flags, p.bytes, p.host);
    if (!buffer.ok()) return buffer.status();
    *p.buffer = std::move(buffer).value();
  }
  // A tick of one character, its one vertex's arrays in an arena of 16-word (64-byte)
  // blocks: joints, weights, positions, normals, tangents; outputs at 0, 4 and 8.
  std::vector<uint32_t> arena(5 * 16, 0);
  std::memcpy(&arena[16], weights.data(), weights.size() * sizeof(float));
  std::memcpy(&arena[48], normal, sizeof(normal));
  std::memcpy(&arena[64], tangent, sizeof(tangent));
  const uint32_t table[kTickFields] = {1, 0, 0, 16, 32, 0, 48, 4, 64, 8, 12};
  const Plan tick[] = {
      {"warm tick arena", &w.tick_arena, kIn, arena.size() * sizeof(uint32_t), arena.data()},
      {"warm tick table", &w.tick_table, kIn, sizeof(table), table},
      {"warm tick output", &w.tick_out, CL_MEM_WRITE_ONLY, 12 * sizeof(float), nullptr}};
  for (const Plan& p : tick) {
    auto buffer = CreateBuffer(p.what, p.flags, p.bytes, p.host);
    if (!buffer.ok()) return buffer.status();
    *p.buffer = std::move(buffer).value();
  }
  return buffers;
}

Status OpenClRuntime::Warm() {
  auto buffers = CreateWarmUpBuffers();
  if (!buffers.ok()) return buffers.status();
  for (auto& lane : lanes_) {
    if (Status s = WarmSkinKernels(*lane, **buffers); !s.ok()) return s;
    if (Status s = WarmMorphKernels(*lane, **buffers); !s.ok()) return s;
    // PoCL compiles each kernel at its first launch, which for 24 tick kernels (48 with the
    // local palette) costs seconds that most engines (every test's) never use: on a CPU
    // device a tick's first launch of each shape pays for it instead.
    if (!is_cpu_) {
      if (Status s = WarmTickKernels(*lane, **buffers); !s.ok()) return s;
    }
    if (cl_int err = clFinish(lane->compute); err != CL_SUCCESS) {
      return ClError("clFinish(warm-up)", err);
    }
  }
  return Status::Ok();
}

Status OpenClRuntime::WarmSkinKernels(OpenClLane& lane, const WarmUpBuffers& w) {
  MeshArrays arrays{.vertex_count = 1,
                    .influences = kMaxInfluences,
                    .joint_count = 1,
                    .positions = {0, 0, 0},
                    .normals = {0, 0, 1}};
  // Each B needs its own mesh shape; the buffers are large enough for every B.
  for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
    arrays.influences = b;
    arrays.joints.assign(b, 0);
    arrays.weights.assign(b, 1.0f / static_cast<float>(b));
    auto mesh = Mesh::Create(arrays);
    if (!mesh.ok()) return mesh.status();
    // (The identity's first 8 floats read as a unit dual quaternion too.)
    for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
      SkinKernelArgs args{.method = method,
                          .palette = w.palette.get(),
                          .joints = w.joints.get(),
                          .weights = w.weights.get(),
                          .positions = w.positions.get(),
                          .out_positions = w.out.get()};
      // Both variants where the local ones are built: a frame may take either; each with
      // positions alone, with normals, with normals and tangents.
      for (bool local : {false, true}) {
        if (local && !local_palette()) continue;
        for (int outputs = 0; outputs < 3; ++outputs) {
          args.normals = outputs >= 1 ? w.normals.get() : nullptr;
          args.out_normals = outputs >= 1 ? w.out_normals.get() : nullptr;
          args.tangents = outputs == 2 ? w.tangents.get() : nullptr;
          args.out_tangents = outputs == 2 ? w.out_tangents.get() : nullptr;
          if (Status s = EnqueueSkinKernel(lane, **mesh, args, 0, 1, local, nullptr); !s.ok()) {
            return s;
          }
        }
      }
    }
  }
  return Status::Ok();
}

Status OpenClRuntime::WarmTickKernels(OpenClLane& lane, const WarmUpBuffers& w) {
  TickLaunch launch{.arena = w.tick_arena.get(),
                    .table = w.tick_table.get(),
                    .palettes = w.palette.get(),
                    .out = w.tick_out.get(),
                    .characters = 1,
                    .most_vertices = 1,
                    .staged_bytes = 12 * sizeof(float)};
  for (bool local : {false, true}) {
    if (local && !local_palette()) continue;
    launch.local = local;
    for (int outputs = 0; outputs < 3; ++outputs) {
      launch.outputs = outputs;
      for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
        launch.influences = b;
        if (Status s = EnqueueTick(lane, launch, nullptr); !s.ok()) return s;
      }
    }
  }
  return Status::Ok();
}

Status OpenClRuntime::WarmMorphKernels(OpenClLane& lane, const WarmUpBuffers& w) {
  MorphKernelArgs morph{.positions = w.positions.get(),
                        .offsets = w.morph_offsets.get(),
                        .indices = w.morph_indices.get(),
                        .position_deltas = w.morph_deltas.get(),
                        .weights = w.morph_weights.get(),
                        .weight_count = 1,
                        .morphed_positions = w.morphed.get()};
  for (bool normals : {false, true}) {
    for (bool tangents : {false, true}) {
      morph.normals = normals ? w.normals.get() : nullptr;
      morph.normal_deltas = normals ? w.morph_deltas.get() : nullptr;
      morph.morphed_normals = normals ? w.morphed_normals.get() : nullptr;
      morph.tangents = tangents ? w.tangents.get() : nullptr;
      morph.tangent_deltas = tangents ? w.morph_deltas.get() : nullptr;
      morph.morphed_tangents = tangents ? w.morphed_tangents.get() : nullptr;
      if (Status s = EnqueueMorph(lane, 1, morph, nullptr); !s.ok()) return s;
    }
  }
  return Status::Ok();
}

}  // namespace skinserve
