// OpenClRuntime: the one platform, device, context, in-order queue and built program an
// engine shares between its OpenCL backends, created once at start-up.
#pragma once

#include <CL/cl.h>

#include <array>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "skinserve/core/mesh.h"
#include "skinserve/core/status.h"

namespace skinserve {

// "CL_INVALID_VALUE" for -30; "CL_UNKNOWN_ERROR" for codes OpenCL 1.2 does not define.
const char* ClErrorName(cl_int code);
// "clCreateBuffer(palette) failed: CL_INVALID_VALUE (-30)". Out-of-memory codes map to
// RESOURCE_EXHAUSTED, every other code to INTERNAL.
Status ClError(const char* call, cl_int code);

// Owns one cl_mem.
class ClBuffer {
 public:
  ClBuffer() = default;
  explicit ClBuffer(cl_mem mem) : mem_(mem) {}
  ClBuffer(ClBuffer&& other) noexcept : mem_(std::exchange(other.mem_, nullptr)) {}
  ClBuffer& operator=(ClBuffer&& other) noexcept {
    std::swap(mem_, other.mem_);
    return *this;
  }
  ClBuffer(const ClBuffer&) = delete;
  ClBuffer& operator=(const ClBuffer&) = delete;
  ~ClBuffer() {
    if (mem_ != nullptr) clReleaseMemObject(mem_);
  }
  cl_mem get() const { return mem_; }

 private:
  cl_mem mem_ = nullptr;
};

// The device-side arrays of one frame. `normals` and `out_normals` are null when the
// frame skips normals.
struct SkinKernelArgs {
  cl_mem palette = nullptr;
  cl_mem joints = nullptr;
  cl_mem weights = nullptr;
  cl_mem positions = nullptr;
  cl_mem out_positions = nullptr;
  cl_mem normals = nullptr;
  cl_mem out_normals = nullptr;
};

class OpenClRuntime {
 public:
  // Picks the first device of the first platform that has one, sets PoCL's thread count
  // to `threads` (unless POCL_MAX_PTHREAD_COUNT is set), builds the program and runs
  // every kernel once so that PoCL has compiled them before the first real frame.
  // FAILED_PRECONDITION (no platform, no device, build log) or the failing call's error.
  static Result<std::shared_ptr<OpenClRuntime>> Create(int threads);
  ~OpenClRuntime();
  OpenClRuntime(const OpenClRuntime&) = delete;
  OpenClRuntime& operator=(const OpenClRuntime&) = delete;

  cl_command_queue queue() const { return queue_; }
  // Frames are serialised: kernel arguments belong to the kernel object, not to a call,
  // and one frame already occupies every PoCL thread.
  std::mutex& mutex() { return mutex_; }
  // Sets the arguments of the kernel for `mesh`'s influence count (with normals when
  // args.out_normals is set) and enqueues it over every vertex. The caller holds mutex().
  Status EnqueueSkin(const Mesh& mesh, const SkinKernelArgs& args);
  // A buffer: device memory (host == nullptr), a copy of `host`, or `host` used in place
  // (CL_MEM_USE_HOST_PTR). `what` names the buffer in errors.
  Result<ClBuffer> CreateBuffer(const char* what, cl_mem_flags flags, std::size_t bytes,
                                const void* host);

  const std::string& device_name() const { return device_name_; }
  // The platform's version, e.g. "OpenCL 3.0 PoCL 3.1+debian".
  const std::string& platform_version() const { return platform_version_; }
  // Compute units: PoCL's worker threads on its CPU device.
  int compute_units() const { return compute_units_; }
  int vector_width() const { return vector_width_; }

 private:
  OpenClRuntime() = default;
  Status Build();
  Status Warm();

  cl_device_id device_ = nullptr;
  cl_context context_ = nullptr;
  cl_command_queue queue_ = nullptr;
  cl_program program_ = nullptr;
  // [with normals][influences - 1]
  std::array<std::array<cl_kernel, kMaxInfluences>, 2> kernels_ = {};
  std::mutex mutex_;
  std::string device_name_;
  std::string platform_version_;
  int compute_units_ = 1;
  int vector_width_ = 1;
};

}  // namespace skinserve
