#include "vulkan_device.h"

#include <fmt/format.h>

#include <cstring>
#include <vector>

#include "host_buffer.h"

namespace skinserve::gpu_region {

Status VkFailed(const char* call, VkResult result) {
  return FailedPrecondition(fmt::format("{} failed: VkResult {}", call, static_cast<int>(result)));
}

namespace {

bool HasDeviceExtension(VkPhysicalDevice device, const char* name) {
  uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> extensions(count);
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, extensions.data());
  for (const auto& e : extensions) {
    if (std::strcmp(e.extensionName, name) == 0) return true;
  }
  return false;
}

// The first queue family with graphics (the renderer draws), else the first with transfer
// (graphics and compute queues have it implicitly).
uint32_t QueueFamily(VkPhysicalDevice device) {
  uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(device, &count, families.data());
  for (uint32_t i = 0; i < count; ++i) {
    if (families[i].queueFlags & VK_QUEUE_GRAPHICS_BIT) return i;
  }
  for (uint32_t i = 0; i < count; ++i) {
    if (families[i].queueFlags &
        (VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT | VK_QUEUE_TRANSFER_BIT)) {
      return i;
    }
  }
  return 0;
}

Result<VkPhysicalDevice> PickDevice(VkInstance instance, int index) {
  uint32_t count = 0;
  vkEnumeratePhysicalDevices(instance, &count, nullptr);
  std::vector<VkPhysicalDevice> devices(count);
  vkEnumeratePhysicalDevices(instance, &count, devices.data());
  if (count == 0) return FailedPrecondition("Vulkan reports no physical device");
  if (index >= 0) {
    if (static_cast<uint32_t>(index) >= count) {
      return InvalidArgument(fmt::format("--vulkan-device {}: there are {} devices", index, count));
    }
    return devices[index];
  }
  for (VkPhysicalDevice d : devices) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(d, &p);
    if (p.deviceType == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU) return d;
  }
  return devices[0];
}

}  // namespace

Result<std::unique_ptr<VulkanDevice>> VulkanDevice::Create(int index, bool memory_fd,
                                                           bool semaphore_fd) {
  std::unique_ptr<VulkanDevice> d(new VulkanDevice());
  VkApplicationInfo app{.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
                        .pApplicationName = "skinserve-gpu-region",
                        .apiVersion = VK_API_VERSION_1_1};
  VkInstanceCreateInfo instance_info{.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                     .pApplicationInfo = &app};
  if (VkResult r = vkCreateInstance(&instance_info, nullptr, &d->instance_); r != VK_SUCCESS) {
    return FailedPrecondition(fmt::format(
        "vkCreateInstance failed (VkResult {}): no Vulkan driver here? (the GPU machine needs "
        "libvulkan1 with the glvnd libraries, and VK_DRIVER_FILES naming NVIDIA's ICD)",
        static_cast<int>(r)));
  }
  Result<VkPhysicalDevice> physical = PickDevice(d->instance_, index);
  if (!physical.ok()) return physical.status();
  d->physical_ = *physical;
  VkPhysicalDeviceIDProperties id{.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES};
  VkPhysicalDeviceProperties2 props{.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2,
                                    .pNext = &id};
  vkGetPhysicalDeviceProperties2(d->physical_, &props);
  d->name_ = props.properties.deviceName;
  std::memcpy(d->uuid_.data(), id.deviceUUID, 16);
  vkGetPhysicalDeviceMemoryProperties(d->physical_, &d->memory_);
  std::vector<const char*> extensions;
  if (memory_fd) extensions.push_back(VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME);
  if (semaphore_fd) extensions.push_back(VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME);
  for (const char* e : extensions) {
    if (!HasDeviceExtension(d->physical_, e)) {
      return FailedPrecondition(fmt::format("Vulkan device '{}' lacks {}", d->name_, e));
    }
  }
  VkPhysicalDeviceFeatures offered;
  vkGetPhysicalDeviceFeatures(d->physical_, &offered);
  VkPhysicalDeviceFeatures features = {};
  features.largePoints = offered.largePoints;
  d->large_points_ = offered.largePoints == VK_TRUE;
  d->queue_family_ = QueueFamily(d->physical_);
  const float priority = 1;
  VkDeviceQueueCreateInfo queue{.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                .queueFamilyIndex = d->queue_family_,
                                .queueCount = 1,
                                .pQueuePriorities = &priority};
  VkDeviceCreateInfo device_info{.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                                 .queueCreateInfoCount = 1,
                                 .pQueueCreateInfos = &queue,
                                 .enabledExtensionCount = static_cast<uint32_t>(extensions.size()),
                                 .ppEnabledExtensionNames = extensions.data(),
                                 .pEnabledFeatures = &features};
  if (VkResult r = vkCreateDevice(d->physical_, &device_info, nullptr, &d->device_);
      r != VK_SUCCESS) {
    return VkFailed("vkCreateDevice", r);
  }
  vkGetDeviceQueue(d->device_, d->queue_family_, 0, &d->queue_);
  if (memory_fd) {
    d->get_memory_fd_ =
        reinterpret_cast<PFN_vkGetMemoryFdKHR>(vkGetDeviceProcAddr(d->device_, "vkGetMemoryFdKHR"));
    if (d->get_memory_fd_ == nullptr) return FailedPrecondition("vkGetMemoryFdKHR is missing");
  }
  if (semaphore_fd) {
    d->get_semaphore_fd_ = reinterpret_cast<PFN_vkGetSemaphoreFdKHR>(
        vkGetDeviceProcAddr(d->device_, "vkGetSemaphoreFdKHR"));
    if (d->get_semaphore_fd_ == nullptr) {
      return FailedPrecondition("vkGetSemaphoreFdKHR is missing");
    }
  }
  return d;
}

VulkanDevice::~VulkanDevice() {
  if (device_ != VK_NULL_HANDLE) vkDestroyDevice(device_, nullptr);
  if (instance_ != VK_NULL_HANDLE) vkDestroyInstance(instance_, nullptr);
}

uint32_t VulkanDevice::MemoryType(uint32_t bits, VkMemoryPropertyFlags flags) const {
  for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    if ((bits & (1u << i)) && (memory_.memoryTypes[i].propertyFlags & flags) == flags) return i;
  }
  return UINT32_MAX;
}

Result<std::unique_ptr<ExportedBuffer>> ExportedBuffer::Create(const VulkanDevice& device,
                                                               uint64_t bytes) {
  std::unique_ptr<ExportedBuffer> b(new ExportedBuffer(device));
  VkExternalMemoryBufferCreateInfo external{
      .sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO,
      .handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT};
  VkBufferCreateInfo info{
      .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
      .pNext = &external,
      .size = bytes,
      .usage = VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
               VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
      .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
  if (VkResult r = vkCreateBuffer(device.device(), &info, nullptr, &b->buffer_); r != VK_SUCCESS) {
    return VkFailed("vkCreateBuffer(exported vertex buffer)", r);
  }
  VkMemoryRequirements needs;
  vkGetBufferMemoryRequirements(device.device(), b->buffer_, &needs);
  const uint32_t type =
      device.MemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (type == UINT32_MAX) return FailedPrecondition("no device-local memory type for the buffer");
  VkMemoryDedicatedAllocateInfo dedicated{.sType = VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO,
                                          .buffer = b->buffer_};
  VkExportMemoryAllocateInfo exported{.sType = VK_STRUCTURE_TYPE_EXPORT_MEMORY_ALLOCATE_INFO,
                                      .pNext = &dedicated,
                                      .handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT};
  VkMemoryAllocateInfo allocate{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .pNext = &exported,
                                .allocationSize = needs.size,
                                .memoryTypeIndex = type};
  if (VkResult r = vkAllocateMemory(device.device(), &allocate, nullptr, &b->memory_);
      r != VK_SUCCESS) {
    return VkFailed("vkAllocateMemory(exportable, dedicated)", r);
  }
  b->allocation_bytes_ = needs.size;
  if (VkResult r = vkBindBufferMemory(device.device(), b->buffer_, b->memory_, 0);
      r != VK_SUCCESS) {
    return VkFailed("vkBindBufferMemory", r);
  }
  return b;
}

ExportedBuffer::~ExportedBuffer() {
  if (buffer_ != VK_NULL_HANDLE) vkDestroyBuffer(device_.device(), buffer_, nullptr);
  if (memory_ != VK_NULL_HANDLE) vkFreeMemory(device_.device(), memory_, nullptr);
}

Result<int> ExportedBuffer::ExportFd() const {
  VkMemoryGetFdInfoKHR info{.sType = VK_STRUCTURE_TYPE_MEMORY_GET_FD_INFO_KHR,
                            .memory = memory_,
                            .handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT};
  int fd = -1;
  if (VkResult r = device_.get_memory_fd()(device_.device(), &info, &fd); r != VK_SUCCESS) {
    return VkFailed("vkGetMemoryFdKHR", r);
  }
  return fd;
}

Result<std::unique_ptr<ExportedSemaphore>> ExportedSemaphore::Create(const VulkanDevice& device) {
  std::unique_ptr<ExportedSemaphore> s(new ExportedSemaphore(device));
  VkExportSemaphoreCreateInfo exported{
      .sType = VK_STRUCTURE_TYPE_EXPORT_SEMAPHORE_CREATE_INFO,
      .handleTypes = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT};
  VkSemaphoreCreateInfo info{.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO, .pNext = &exported};
  if (VkResult r = vkCreateSemaphore(device.device(), &info, nullptr, &s->semaphore_);
      r != VK_SUCCESS) {
    return VkFailed("vkCreateSemaphore(exportable, binary)", r);
  }
  return s;
}

ExportedSemaphore::~ExportedSemaphore() {
  if (semaphore_ != VK_NULL_HANDLE) vkDestroySemaphore(device_.device(), semaphore_, nullptr);
}

Result<int> ExportedSemaphore::ExportFd() const {
  VkSemaphoreGetFdInfoKHR info{.sType = VK_STRUCTURE_TYPE_SEMAPHORE_GET_FD_INFO_KHR,
                               .semaphore = semaphore_,
                               .handleType = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT};
  int fd = -1;
  if (VkResult r = device_.get_semaphore_fd()(device_.device(), &info, &fd); r != VK_SUCCESS) {
    return VkFailed("vkGetSemaphoreFdKHR", r);
  }
  return fd;
}

ReadBack::ReadBack(const VulkanDevice& device) : device_(device) {}

Result<std::unique_ptr<ReadBack>> ReadBack::Create(const VulkanDevice& device, uint64_t bytes) {
  std::unique_ptr<ReadBack> rb(new ReadBack(device));
  auto staging = HostBuffer::CreateMapped(device, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  if (!staging.ok()) return staging.status();
  rb->staging_ = std::move(staging).value();
  rb->bytes_ = bytes;
  VkCommandPoolCreateInfo pool{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                               .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                               .queueFamilyIndex = device.queue_family()};
  vkCreateCommandPool(device.device(), &pool, nullptr, &rb->pool_);
  VkCommandBufferAllocateInfo command{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                      .commandPool = rb->pool_,
                                      .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                      .commandBufferCount = 1};
  vkAllocateCommandBuffers(device.device(), &command, &rb->commands_);
  VkFenceCreateInfo fence{.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  vkCreateFence(device.device(), &fence, nullptr, &rb->fence_);
  return rb;
}

ReadBack::~ReadBack() {
  VkDevice d = device_.device();
  if (fence_ != VK_NULL_HANDLE) vkDestroyFence(d, fence_, nullptr);
  if (pool_ != VK_NULL_HANDLE) vkDestroyCommandPool(d, pool_, nullptr);
}

Result<const void*> ReadBack::Copy(const ExportedBuffer& from, uint64_t offset, uint64_t bytes,
                                   VkSemaphore wait) {
  if (bytes > bytes_) {
    return InvalidArgument(fmt::format("read-back of {} bytes exceeds its {}", bytes, bytes_));
  }
  vkResetCommandBuffer(commands_, 0);
  VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                 .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
  vkBeginCommandBuffer(commands_, &begin);
  // The server's OpenCL wrote the buffer: take it from the external queue family.
  VkBufferMemoryBarrier acquire{.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER,
                                .srcAccessMask = 0,
                                .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT,
                                .srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL,
                                .dstQueueFamilyIndex = device_.queue_family(),
                                .buffer = from.buffer(),
                                .offset = 0,
                                .size = VK_WHOLE_SIZE};
  vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                       0, 0, nullptr, 1, &acquire, 0, nullptr);
  VkBufferCopy region{.srcOffset = offset, .dstOffset = 0, .size = bytes};
  vkCmdCopyBuffer(commands_, from.buffer(), staging_->buffer(), 1, &region);
  // ...and hand it back for the server's next frame.
  VkBufferMemoryBarrier release = acquire;
  release.srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  release.dstAccessMask = 0;
  release.srcQueueFamilyIndex = device_.queue_family();
  release.dstQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
  vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 1, &release, 0,
                       nullptr);
  vkEndCommandBuffer(commands_);
  const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                      .waitSemaphoreCount = wait != VK_NULL_HANDLE ? 1u : 0u,
                      .pWaitSemaphores = &wait,
                      .pWaitDstStageMask = &wait_stage,
                      .commandBufferCount = 1,
                      .pCommandBuffers = &commands_};
  vkResetFences(device_.device(), 1, &fence_);
  if (VkResult r = vkQueueSubmit(device_.queue(), 1, &submit, fence_); r != VK_SUCCESS) {
    return VkFailed("vkQueueSubmit(read-back)", r);
  }
  if (VkResult r = vkWaitForFences(device_.device(), 1, &fence_, VK_TRUE, kFenceTimeoutNs);
      r != VK_SUCCESS) {
    return r == VK_TIMEOUT ? DeadlineExceeded(
                                 "the read-back did not finish within 20 s: was the "
                                 "server's semaphore signalled?")
                           : VkFailed("vkWaitForFences(read-back)", r);
  }
  return static_cast<const void*>(staging_->mapped());
}

}  // namespace skinserve::gpu_region
