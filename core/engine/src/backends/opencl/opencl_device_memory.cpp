// clCreateBufferWithProperties is OpenCL 3.0; the rest of the engine targets 1.2.
#undef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 300

#include "backends/opencl/opencl_device_memory.h"

#include <CL/cl_ext.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <mutex>
#include <vector>

#include "backends/opencl/opencl_semaphore.h"

namespace skinserve {
namespace {

class OpenClDeviceMemory final : public DeviceMemory {
 public:
  OpenClDeviceMemory(ClBuffer buffer, uint64_t bytes, std::string backend,
                     clEnqueueAcquireExternalMemObjectsKHR_fn acquire_fn,
                     clEnqueueReleaseExternalMemObjectsKHR_fn release_fn,
                     std::unique_ptr<ImportedSemaphore> semaphore = nullptr, bool in_place = true)
      : buffer_(std::move(buffer)),
        bytes_(bytes),
        backend_(std::move(backend)),
        acquire_(acquire_fn),
        release_(release_fn),
        semaphore_(std::move(semaphore)),
        in_place_(in_place) {}
  uint64_t byte_size() const override { return bytes_; }
  const std::string& backend() const override { return backend_; }
  bool signals_semaphore() const override { return semaphore_ != nullptr; }
  Status SignalFrameWritten() const override {
    return semaphore_ != nullptr ? semaphore_->Signal() : Status::Ok();
  }
  cl_mem buffer() const { return buffer_.get(); }
  bool imported() const { return acquire_ != nullptr; }
  // Aligned float32 frames are written in place (DirectFloat32Outputs).
  bool in_place() const { return in_place_; }
  clEnqueueAcquireExternalMemObjectsKHR_fn acquire() const { return acquire_; }
  clEnqueueReleaseExternalMemObjectsKHR_fn release() const { return release_; }
  // Frames on different lanes (queues) write it one at a time: an external object is
  // acquired by one queue until it is released.
  std::mutex& in_use() const { return in_use_; }
  // A sub-buffer of the memory at [offset, offset + bytes), retained for the caller: made
  // once per range and kept while the memory lives (a stream writes the same ranges every
  // frame, and NVIDIA's driver makes a sub-buffer slowly), up to kMaxSubBuffers ranges;
  // past that each call makes its own.
  Result<ClBuffer> SubBuffer(uint64_t offset, uint64_t bytes, const char* what) const;

 private:
  static constexpr std::size_t kMaxSubBuffers = 1024;
  ClBuffer buffer_;
  const uint64_t bytes_;
  const std::string backend_;
  // Null for memory of the runtime's own (not imported): nothing to acquire.
  const clEnqueueAcquireExternalMemObjectsKHR_fn acquire_;
  const clEnqueueReleaseExternalMemObjectsKHR_fn release_;
  const std::unique_ptr<ImportedSemaphore> semaphore_;  // null: none registered
  const bool in_place_;
  mutable std::mutex in_use_;
  mutable std::mutex sub_buffers_mutex_;
  mutable std::map<std::pair<uint64_t, uint64_t>, ClBuffer> sub_buffers_;  // (offset, bytes)
};

Result<ClBuffer> OpenClDeviceMemory::SubBuffer(uint64_t offset, uint64_t bytes,
                                               const char* what) const {
  std::lock_guard<std::mutex> lock(sub_buffers_mutex_);
  const auto key = std::make_pair(offset, bytes);
  if (auto it = sub_buffers_.find(key); it != sub_buffers_.end()) {
    if (cl_int err = clRetainMemObject(it->second.get()); err != CL_SUCCESS) {
      return ClError("clRetainMemObject", err);
    }
    return ClBuffer(it->second.get());
  }
  const cl_buffer_region region{offset, bytes};
  cl_int err = CL_SUCCESS;
  ClBuffer made(clCreateSubBuffer(buffer_.get(), CL_MEM_WRITE_ONLY, CL_BUFFER_CREATE_TYPE_REGION,
                                  &region, &err));
  if (err != CL_SUCCESS) return ClError(what, err);
  if (sub_buffers_.size() >= kMaxSubBuffers) return made;
  if (cl_int retain = clRetainMemObject(made.get()); retain != CL_SUCCESS) {
    return ClError("clRetainMemObject", retain);
  }
  ClBuffer caller(made.get());
  sub_buffers_.emplace(key, std::move(made));
  return caller;
}

Result<std::string> DeviceText(cl_device_id device, cl_device_info what, const char* name) {
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

std::string Hex(const uint8_t* bytes, std::size_t n) {
  std::string out;
  for (std::size_t i = 0; i < n; ++i) out += fmt::format("{:02x}", bytes[i]);
  return out;
}

// FAILED_PRECONDITION naming the first extension the device lacks, or OK.
Status CheckImportExtensions(const OpenClRuntime& runtime, const std::string& extensions,
                             bool with_semaphore) {
  const char* missing = MissingImportExtension(extensions, with_semaphore);
  if (missing == nullptr) return Status::Ok();
  return FailedPrecondition(fmt::format(
      "the opencl backend's device '{}' ({}) cannot import {}: it lacks {} (GPU regions need "
      "cl_khr_external_memory_opaque_fd and cl_khr_device_uuid, a semaphore beside them "
      "cl_khr_semaphore and cl_khr_external_semaphore_opaque_fd; PoCL offers no external "
      "memory)",
      runtime.device_name(), runtime.platform_version(),
      with_semaphore ? "GPU memory with a semaphore" : "GPU memory", missing));
}

Status CheckUuid(const OpenClRuntime& runtime, const DeviceMemoryImport& import) {
  uint8_t uuid[CL_UUID_SIZE_KHR] = {};
  if (cl_int err =
          clGetDeviceInfo(runtime.device(), CL_DEVICE_UUID_KHR, sizeof(uuid), uuid, nullptr);
      err != CL_SUCCESS) {
    return ClError("clGetDeviceInfo(CL_DEVICE_UUID_KHR)", err);
  }
  if (std::memcmp(uuid, import.device_uuid.data(), sizeof(uuid)) != 0) {
    return FailedPrecondition(fmt::format(
        "device_uuid {} is not the opencl backend's device '{}' (UUID {}): the server imports "
        "memory only of the device it skins on",
        Hex(import.device_uuid.data(), 16), runtime.device_name(), Hex(uuid, sizeof(uuid))));
  }
  return Status::Ok();
}

template <typename Fn>
Fn Extension(cl_platform_id platform, const char* name) {
  return reinterpret_cast<Fn>(clGetExtensionFunctionAddressForPlatform(platform, name));
}

}  // namespace

Result<std::shared_ptr<DeviceMemory>> ImportOpenClDeviceMemory(const OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               const DeviceMemoryImport& import) {
  Result<std::string> extensions =
      DeviceText(runtime.device(), CL_DEVICE_EXTENSIONS, "clGetDeviceInfo(CL_DEVICE_EXTENSIONS)");
  if (!extensions.ok()) return extensions.status();
  const bool with_semaphore = import.semaphore_fd >= 0;
  if (Status s = CheckImportExtensions(runtime, *extensions, with_semaphore); !s.ok()) return s;
  if (Status s = CheckUuid(runtime, import); !s.ok()) return s;
  cl_platform_id platform = nullptr;
  if (cl_int err = clGetDeviceInfo(runtime.device(), CL_DEVICE_PLATFORM, sizeof(platform),
                                   &platform, nullptr);
      err != CL_SUCCESS) {
    return ClError("clGetDeviceInfo(CL_DEVICE_PLATFORM)", err);
  }
  auto acquire = Extension<clEnqueueAcquireExternalMemObjectsKHR_fn>(
      platform, "clEnqueueAcquireExternalMemObjectsKHR");
  auto release = Extension<clEnqueueReleaseExternalMemObjectsKHR_fn>(
      platform, "clEnqueueReleaseExternalMemObjectsKHR");
  if (acquire == nullptr || release == nullptr) {
    return FailedPrecondition(fmt::format(
        "the opencl backend's device '{}' lists cl_khr_external_memory but its platform has no "
        "clEnqueueAcquireExternalMemObjectsKHR / clEnqueueReleaseExternalMemObjectsKHR",
        runtime.device_name()));
  }
  // The semaphore first: it imports a duplicate, so a failed memory import after it
  // leaves both of the caller's fds as they were.
  std::unique_ptr<ImportedSemaphore> semaphore;
  if (with_semaphore) {
    Result<std::unique_ptr<ImportedSemaphore>> imported =
        ImportedSemaphore::Import(runtime, import.semaphore_fd);
    if (!imported.ok()) return imported.status();
    semaphore = std::move(imported).value();
  }
  // As checked on the H200 (../shared/notes/gpu-machine.md): the fd alone; the context
  // has the one device.
  const cl_mem_properties properties[] = {CL_EXTERNAL_MEMORY_HANDLE_OPAQUE_FD_KHR,
                                          static_cast<cl_mem_properties>(import.fd), 0};
  cl_int err = CL_SUCCESS;
  cl_mem mem = clCreateBufferWithProperties(runtime.context(), properties, CL_MEM_READ_WRITE,
                                            import.byte_size, nullptr, &err);
  if (err != CL_SUCCESS) return ClError("clCreateBufferWithProperties(opaque fd)", err);
  if (with_semaphore) close(import.semaphore_fd);  // imported: ours, and the driver has its own
  return std::shared_ptr<DeviceMemory>(std::make_shared<OpenClDeviceMemory>(
      ClBuffer(mem), import.byte_size, backend, acquire, release, std::move(semaphore)));
}

Result<std::shared_ptr<DeviceMemory>> CreateOpenClDeviceMemory(OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               uint64_t bytes, bool in_place) {
  Result<ClBuffer> buffer =
      runtime.CreateBuffer("device memory", CL_MEM_READ_WRITE, bytes, nullptr);
  if (!buffer.ok()) return buffer.status();
  return std::shared_ptr<DeviceMemory>(std::make_shared<OpenClDeviceMemory>(
      std::move(buffer).value(), bytes, backend, nullptr, nullptr, nullptr, in_place));
}

cl_mem OpenClDeviceMemoryBuffer(const DeviceMemory& memory) {
  const auto* cl = dynamic_cast<const OpenClDeviceMemory*>(&memory);
  return cl != nullptr ? cl->buffer() : nullptr;
}

DeviceOutputBatch::~DeviceOutputBatch() {
  if (!finished_) (void)Finish();  // an error path: the first error was returned already
}

Status DeviceOutputBatch::Hold(const SkinFrame& frame, ClEvents& transfers) {
  const auto* memory = dynamic_cast<const OpenClDeviceMemory*>(frame.device.memory);
  if (memory == nullptr) {
    return FailedPrecondition("the frame's device memory was not made by the opencl backend");
  }
  const bool held =
      std::any_of(held_.begin(), held_.end(), [&](const Held& h) { return h.memory == memory; });
  if (held) return Status::Ok();
  held_.push_back({memory, std::unique_lock(memory->in_use())});
  if (memory->imported()) {
    cl_mem target = memory->buffer();
    if (cl_int err = memory->acquire()(lane_.compute, 1, &target, 0, nullptr, transfers.Next());
        err != CL_SUCCESS) {
      held_.pop_back();  // not acquired: nothing to release
      return ClError("clEnqueueAcquireExternalMemObjectsKHR", err);
    }
  }
  return Status::Ok();
}

Status DeviceOutputBatch::Enqueue(const SkinFrame& frame, std::span<const DeviceOutputPiece> pieces,
                                  ClEvents& transfers) {
  if (Status s = Hold(frame, transfers); !s.ok()) return s;
  cl_mem target = OpenClDeviceMemoryBuffer(*frame.device.memory);
  for (const DeviceOutputPiece& p : pieces) {
    const cl_int err = p.from != nullptr
                           ? clEnqueueCopyBuffer(lane_.compute, p.from, target, 0, p.offset,
                                                 p.bytes, 0, nullptr, transfers.Next())
                           : clEnqueueWriteBuffer(lane_.compute, target, CL_FALSE, p.offset,
                                                  p.bytes, p.host, 0, nullptr, transfers.Next());
    if (err != CL_SUCCESS) return ClError(p.what, err);
  }
  return Status::Ok();
}

Status DeviceOutputBatch::Finish() {
  finished_ = true;
  Status status;
  for (const Held& h : held_) {
    const auto* memory = static_cast<const OpenClDeviceMemory*>(h.memory);
    if (!memory->imported()) continue;
    cl_mem target = memory->buffer();
    if (cl_int err = memory->release()(lane_.compute, 1, &target, 0, nullptr, nullptr);
        err != CL_SUCCESS && status.ok()) {
      status = ClError("clEnqueueReleaseExternalMemObjectsKHR", err);
    }
  }
  // The answers say the frames are in the memory: they must be there when the answers go
  // (and a host piece's bytes are the caller's only until then).
  if (cl_int err = clFinish(lane_.compute); err != CL_SUCCESS && status.ok()) {
    status = ClError("clFinish", err);
  }
  held_.clear();  // unlocks
  return status;
}

Status WriteDevicePieces(OpenClLane& lane, const SkinFrame& frame,
                         std::span<const DeviceOutputPiece> pieces, ClEvents& transfers) {
  DeviceOutputBatch batch(lane);
  if (Status s = batch.Enqueue(frame, pieces, transfers); !s.ok()) return s;
  return batch.Finish();
}

namespace {
std::atomic<uint64_t> in_place_frames{0};
}  // namespace

uint64_t InPlaceDeviceFrames() { return in_place_frames.load(); }

Result<DirectDeviceOutputs> DirectFloat32Outputs(const SkinFrame& frame, uint32_t vertices,
                                                 uint64_t alignment) {
  const DeviceOutput& device = frame.device;
  DirectDeviceOutputs direct;
  const auto* cl = dynamic_cast<const OpenClDeviceMemory*>(device.memory);
  const cl_mem memory = cl != nullptr ? cl->buffer() : nullptr;
  const auto aligned = [&](uint64_t offset) { return offset % alignment == 0; };
  if (memory == nullptr || !cl->in_place() || device.encoding != VertexEncoding::kFloat32 ||
      !aligned(device.positions_offset) || (device.normals && !aligned(device.normals_offset)) ||
      (device.tangents && !aligned(device.tangents_offset))) {
    return direct;
  }
  const auto sub = [&](const char* what, uint64_t offset, uint64_t bytes, ClBuffer* out) -> Status {
    Result<ClBuffer> buffer = cl->SubBuffer(offset, bytes, what);
    if (!buffer.ok()) return buffer.status();
    *out = std::move(*buffer);
    return Status::Ok();
  };
  const uint64_t array_bytes = 3ull * sizeof(float) * vertices;
  if (Status s = sub("clCreateSubBuffer(positions)", device.positions_offset, array_bytes,
                     &direct.positions);
      !s.ok()) {
    return s;
  }
  if (device.normals) {
    if (Status s =
            sub("clCreateSubBuffer(normals)", device.normals_offset, array_bytes, &direct.normals);
        !s.ok()) {
      return s;
    }
  }
  if (device.tangents) {
    if (Status s = sub("clCreateSubBuffer(tangents)", device.tangents_offset,
                       4ull * sizeof(float) * vertices, &direct.tangents);
        !s.ok()) {
      return s;
    }
  }
  in_place_frames.fetch_add(1);
  return direct;
}

std::vector<DeviceOutputPiece> Float32DevicePieces(const SkinKernelArgs& args, uint32_t vertices,
                                                   const DeviceOutput& device) {
  const uint64_t array_bytes = 3ull * sizeof(float) * vertices;
  std::vector<DeviceOutputPiece> pieces = {{"clEnqueueCopyBuffer(positions)", args.out_positions,
                                            nullptr, device.positions_offset, array_bytes}};
  if (device.normals) {
    pieces.push_back({"clEnqueueCopyBuffer(normals)", args.out_normals, nullptr,
                      device.normals_offset, array_bytes});
  }
  if (device.tangents) {
    pieces.push_back({"clEnqueueCopyBuffer(tangents)", args.out_tangents, nullptr,
                      device.tangents_offset, 4ull * sizeof(float) * vertices});
  }
  return pieces;
}

}  // namespace skinserve
