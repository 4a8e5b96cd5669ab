// The headless Vulkan side of skinserve-gpu-region: one device (by index, or the first
// discrete GPU), a vertex buffer in device-local memory exported as an opaque file
// descriptor (VK_KHR_external_memory_fd, a dedicated allocation: what NVIDIA's OpenCL
// imports), and a read-back of part of it through host-visible memory for the test mode.
#pragma once

#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::gpu_region {

// FAILED_PRECONDITION naming the Vulkan call that failed and its VkResult.
Status VkFailed(const char* call, VkResult result);

// How long a submission that waits on the server's semaphore may take: a signal that never
// comes fails the run (VK_TIMEOUT) instead of hanging it.
inline constexpr uint64_t kFenceTimeoutNs = 20'000'000'000;

class VulkanDevice {
 public:
  // `index` < 0: the first discrete GPU, else the first device. FAILED_PRECONDITION with
  // what is missing (no loader or driver, no device; with `memory_fd`, no
  // VK_KHR_external_memory_fd; with `semaphore_fd`, no VK_KHR_external_semaphore_fd).
  // Without either (the drawing test on a CPU's Vulkan) nothing is exported.
  static Result<std::unique_ptr<VulkanDevice>> Create(int index, bool memory_fd = true,
                                                      bool semaphore_fd = true);
  ~VulkanDevice();
  VulkanDevice(const VulkanDevice&) = delete;
  VulkanDevice& operator=(const VulkanDevice&) = delete;

  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const std::array<uint8_t, 16>& uuid() const { return uuid_; }  // deviceUUID
  const std::string& name() const { return name_; }
  // A memory type among `bits` with `flags`; UINT32_MAX if none.
  uint32_t MemoryType(uint32_t bits, VkMemoryPropertyFlags flags) const;
  PFN_vkGetMemoryFdKHR get_memory_fd() const { return get_memory_fd_; }
  PFN_vkGetSemaphoreFdKHR get_semaphore_fd() const { return get_semaphore_fd_; }
  bool large_points() const { return large_points_; }  // gl_PointSize above 1

 private:
  VulkanDevice() = default;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  std::array<uint8_t, 16> uuid_ = {};
  std::string name_;
  VkPhysicalDeviceMemoryProperties memory_ = {};
  PFN_vkGetMemoryFdKHR get_memory_fd_ = nullptr;
  PFN_vkGetSemaphoreFdKHR get_semaphore_fd_ = nullptr;
  bool large_points_ = false;
};

// A binary semaphore exportable as an opaque fd (VK_KHR_external_semaphore_fd): the
// server signals it once per frame it answers into the GPU region (its registration's
// semaphore_fd_token), and the client's next GPU work on the region waits on it.
class ExportedSemaphore {
 public:
  static Result<std::unique_ptr<ExportedSemaphore>> Create(const VulkanDevice& device);
  ~ExportedSemaphore();
  ExportedSemaphore(const ExportedSemaphore&) = delete;
  ExportedSemaphore& operator=(const ExportedSemaphore&) = delete;
  // A new fd of the semaphore (vkGetSemaphoreFdKHR): the caller's to close.
  Result<int> ExportFd() const;
  VkSemaphore semaphore() const { return semaphore_; }

 private:
  explicit ExportedSemaphore(const VulkanDevice& device) : device_(device) {}
  const VulkanDevice& device_;
  VkSemaphore semaphore_ = VK_NULL_HANDLE;
};

// A vertex buffer of device-local memory, exportable as an opaque fd.
class ExportedBuffer {
 public:
  static Result<std::unique_ptr<ExportedBuffer>> Create(const VulkanDevice& device, uint64_t bytes);
  ~ExportedBuffer();
  ExportedBuffer(const ExportedBuffer&) = delete;
  ExportedBuffer& operator=(const ExportedBuffer&) = delete;
  // A new fd of the memory (vkGetMemoryFdKHR): the caller's to close.
  Result<int> ExportFd() const;
  VkBuffer buffer() const { return buffer_; }
  uint64_t allocation_bytes() const { return allocation_bytes_; }  // what the fd covers

 private:
  explicit ExportedBuffer(const VulkanDevice& device) : device_(device) {}
  const VulkanDevice& device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  uint64_t allocation_bytes_ = 0;
};

// Copies ranges of an ExportedBuffer to the host (the test mode's check), taking the
// buffer from the external queue family (the server's OpenCL wrote it) first.
class HostBuffer;

class ReadBack {
 public:
  static Result<std::unique_ptr<ReadBack>> Create(const VulkanDevice& device, uint64_t bytes);
  ~ReadBack();
  ReadBack(const ReadBack&) = delete;
  ReadBack& operator=(const ReadBack&) = delete;
  // [offset, offset + bytes) of `from` into the returned host memory (valid until the next
  // call). With `wait` (not VK_NULL_HANDLE) the copy waits on that semaphore on the GPU,
  // consuming the server's one signal for the frame.
  Result<const void*> Copy(const ExportedBuffer& from, uint64_t offset, uint64_t bytes,
                           VkSemaphore wait = VK_NULL_HANDLE);

 private:
  explicit ReadBack(const VulkanDevice& device);  // in the .cpp, where HostBuffer is complete
  const VulkanDevice& device_;
  std::unique_ptr<HostBuffer> staging_;  // host-visible, mapped: where the copy lands
  uint64_t bytes_ = 0;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkCommandBuffer commands_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
};

}  // namespace skinserve::gpu_region
