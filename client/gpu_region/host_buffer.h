// A Vulkan buffer in host-visible, coherent memory, mapped while it lives: filled once from
// the host (the index buffer of --mesh's triangles, which the renderer reads where it lies;
// the vertices of the drawing test's scenes), or where GPU copies land for the host to read
// (ReadBack's staging).
#pragma once

#include <vulkan/vulkan.h>

#include <cstddef>
#include <memory>

#include "skinserve/model/status.h"
#include "vulkan_device.h"

namespace skinserve::gpu_region {

class HostBuffer {
 public:
  // `bytes` of `data` (> 0) in a buffer of `usage` (e.g. VK_BUFFER_USAGE_INDEX_BUFFER_BIT).
  // FAILED_PRECONDITION naming the Vulkan call that failed.
  static Result<std::unique_ptr<HostBuffer>> Create(const VulkanDevice& device, const void* data,
                                                    std::size_t bytes, VkBufferUsageFlags usage);
  // `bytes` (> 0) left as they come, for the GPU to write (e.g. VK_BUFFER_USAGE_TRANSFER_DST_BIT).
  static Result<std::unique_ptr<HostBuffer>> CreateMapped(const VulkanDevice& device,
                                                          std::size_t bytes,
                                                          VkBufferUsageFlags usage);
  ~HostBuffer();
  HostBuffer(const HostBuffer&) = delete;
  HostBuffer& operator=(const HostBuffer&) = delete;
  VkBuffer buffer() const { return buffer_; }
  void* mapped() const { return mapped_; }

 private:
  explicit HostBuffer(const VulkanDevice& device) : device_(device) {}
  const VulkanDevice& device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
};

}  // namespace skinserve::gpu_region
