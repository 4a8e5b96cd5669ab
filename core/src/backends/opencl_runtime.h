// OpenClRuntime: the one platform, device, context, in-order queue and built program an
// engine shares between its OpenCL backends, created once at start-up.
#pragma once

#include <CL/cl.h>

#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "skinserve/core/mesh.h"
#include "skinserve/core/status.h"

namespace skinserve {

const char* ClErrorName(cl_int code);
// "clCreateBuffer failed: CL_INVALID_VALUE (-30)".
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

// The device-side arrays of one frame. `normals` and `out_normals` may be null when the
// frame skips normals.
struct SkinKernelArgs {
  cl_mem palette, positions, normals, joints, weights, out_positions, out_normals;
};

class OpenClRuntime {
 public:
  // Picks the first device of the first platform, sets PoCL's thread count to `threads`
  // (unless POCL_MAX_PTHREAD_COUNT is set), builds the program and runs every kernel once
  // so that PoCL has compiled them before the first real frame.
  static Result<std::shared_ptr<OpenClRuntime>> Create(int threads);
  ~OpenClRuntime();
  OpenClRuntime(const OpenClRuntime&) = delete;
  OpenClRuntime& operator=(const OpenClRuntime&) = delete;

  cl_context context() const { return context_; }
  cl_command_queue queue() const { return queue_; }
  // Frames are serialised: kernel arguments are per kernel object, not per call.
  std::mutex& mutex() { return mutex_; }
  // Sets the arguments of the kernel for `mesh`'s influence count and enqueues it over
  // every vertex. The caller holds mutex().
  Status EnqueueSkin(const Mesh& mesh, const SkinKernelArgs& args, bool with_normals);
  // A read-only buffer: copied into device memory, or wrapping `host` in place.
  Result<ClBuffer> CreateBuffer(cl_mem_flags flags, std::size_t bytes, const void* host);

  const std::string& device_name() const { return device_name_; }
  const std::string& version() const { return version_; }
  int compute_units() const { return compute_units_; }
  int vector_width() const { return vector_width_; }

 private:
  OpenClRuntime() = default;
  Status Warm();

  cl_device_id device_ = nullptr;
  cl_context context_ = nullptr;
  cl_command_queue queue_ = nullptr;
  cl_program program_ = nullptr;
  cl_kernel kernels_[kMaxInfluences] = {};
  std::mutex mutex_;
  std::string device_name_;
  std::string version_;
  int compute_units_ = 1;
  int vector_width_ = 1;
};

}  // namespace skinserve
