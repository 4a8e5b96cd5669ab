#include "host_buffer.h"

#include <cstring>

namespace skinserve::gpu_region {

Result<std::unique_ptr<HostBuffer>> HostBuffer::CreateMapped(const VulkanDevice& device,
                                                             std::size_t bytes,
                                                             VkBufferUsageFlags usage) {
  if (bytes == 0) return InvalidArgument("a host buffer of 0 bytes");
  std::unique_ptr<HostBuffer> b(new HostBuffer(device));
  VkDevice d = device.device();
  VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                          .size = bytes,
                          .usage = usage,
                          .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
  if (VkResult r = vkCreateBuffer(d, &info, nullptr, &b->buffer_); r != VK_SUCCESS) {
    return VkFailed("vkCreateBuffer(host)", r);
  }
  VkMemoryRequirements needs;
  vkGetBufferMemoryRequirements(d, b->buffer_, &needs);
  const uint32_t type =
      device.MemoryType(needs.memoryTypeBits,
                        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  if (type == UINT32_MAX) return FailedPrecondition("no host-visible coherent memory type");
  VkMemoryAllocateInfo allocate{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .allocationSize = needs.size,
                                .memoryTypeIndex = type};
  if (VkResult r = vkAllocateMemory(d, &allocate, nullptr, &b->memory_); r != VK_SUCCESS) {
    return VkFailed("vkAllocateMemory(host)", r);
  }
  vkBindBufferMemory(d, b->buffer_, b->memory_, 0);
  if (VkResult r = vkMapMemory(d, b->memory_, 0, bytes, 0, &b->mapped_); r != VK_SUCCESS) {
    return VkFailed("vkMapMemory(host)", r);
  }
  return b;
}

Result<std::unique_ptr<HostBuffer>> HostBuffer::Create(const VulkanDevice& device, const void* data,
                                                       std::size_t bytes,
                                                       VkBufferUsageFlags usage) {
  auto b = CreateMapped(device, bytes, usage);
  if (b.ok()) std::memcpy((*b)->mapped(), data, bytes);
  return b;
}

// Freeing the memory unmaps it.
HostBuffer::~HostBuffer() {
  if (buffer_ != VK_NULL_HANDLE) vkDestroyBuffer(device_.device(), buffer_, nullptr);
  if (memory_ != VK_NULL_HANDLE) vkFreeMemory(device_.device(), memory_, nullptr);
}

}  // namespace skinserve::gpu_region
