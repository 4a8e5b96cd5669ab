// VertexRenderer: skinserve-gpu-region's --draw (docs/serving/gpu-regions.md#draw). A small
// Vulkan graphics pipeline that binds a vertex buffer as it lies - the GPU region the
// server writes, float32 x y z positions and, when there, normals at their own offset -
// and draws it into an offscreen colour image with a depth buffer, then copies the image
// back for a PNG. Triangles with an index buffer; points without one (the synthetic
// character has no faces). The shaders are GLSL compiled to SPIR-V at build time
// (shaders/, glslangValidator) and embedded.
#pragma once

#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "skinserve/model/status.h"
#include "vulkan_device.h"

namespace skinserve::gpu_region {

// Column-major 4x4, clip space from the mesh's space.
using Transform = std::array<float, 16>;

// An orthographic front view that fits the box [lo, hi] into a width x height image with a
// margin: x to the right, y up, the nearest z (largest) at depth 0.
Transform FrontView(const std::array<float, 3>& lo, const std::array<float, 3>& hi, uint32_t width,
                    uint32_t height);

// FrontView of the bounds of `positions` (x y z per vertex): the camera framed on a
// character's reference pose.
Transform FrontViewOf(std::span<const double> positions, uint32_t width, uint32_t height);

struct DrawSource {
  VkBuffer vertices = VK_NULL_HANDLE;
  uint64_t positions_offset = 0;
  uint64_t normals_offset = 0;
  bool normals = false;
  uint32_t vertex_count = 0;
  VkBuffer indices = VK_NULL_HANDLE;  // uint32 triangles; none: points
  uint32_t index_count = 0;
  // Written by another API (the server's OpenCL): taken from VK_QUEUE_FAMILY_EXTERNAL
  // before the draw and handed back after it.
  bool external = false;
  VkSemaphore wait = VK_NULL_HANDLE;  // waited on before the vertices are read
  Transform transform = {};
  float point_size = 2;  // 1 where the device lacks largePoints
};

class VertexRenderer {
 public:
  static constexpr std::array<uint8_t, 4> kBackground = {26, 31, 38, 255};  // RGBA
  static Result<std::unique_ptr<VertexRenderer>> Create(const VulkanDevice& device, uint32_t width,
                                                        uint32_t height);
  ~VertexRenderer();
  VertexRenderer(const VertexRenderer&) = delete;
  VertexRenderer& operator=(const VertexRenderer&) = delete;

  // Draws `source` (and waits for it): the image's RGBA8 pixels, row by row from the top,
  // valid until the next Draw.
  Result<std::span<const uint8_t>> Draw(const DrawSource& source);
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }

 private:
  struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
  };
  VertexRenderer(const VulkanDevice& device, uint32_t width, uint32_t height)
      : device_(device), width_(width), height_(height) {}
  Status CreateImage(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect,
                     Image* image);
  Status CreateTargets();
  Status CreateRenderPass();
  Status CreatePipeline(VkPrimitiveTopology topology, VkPipeline* pipeline);
  Status CreateReadBack();
  void RecordDraw(const DrawSource& source);
  void DestroyImage(Image& image);

  const VulkanDevice& device_;
  const uint32_t width_, height_;
  Image color_, depth_;
  VkRenderPass render_pass_ = VK_NULL_HANDLE;
  VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline triangles_ = VK_NULL_HANDLE, points_ = VK_NULL_HANDLE;
  VkBuffer pixels_ = VK_NULL_HANDLE;
  VkDeviceMemory pixels_memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkCommandBuffer commands_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
};

}  // namespace skinserve::gpu_region
