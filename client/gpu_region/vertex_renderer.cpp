#include "vertex_renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

#include "draw_frag.spv.h"  // kDrawFrag: shaders/draw.frag as SPIR-V (CMakeLists.txt)
#include "draw_vert.spv.h"  // kDrawVert

namespace skinserve::gpu_region {
namespace {

constexpr VkFormat kColorFormat = VK_FORMAT_R8G8B8A8_UNORM;
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

struct PushConstants {
  float transform[16];
  float point_size;
  float has_normals;
};

Result<VkShaderModule> Shader(VkDevice device, const uint32_t* code, std::size_t bytes) {
  VkShaderModuleCreateInfo info{
      .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO, .codeSize = bytes, .pCode = code};
  VkShaderModule module = VK_NULL_HANDLE;
  if (VkResult r = vkCreateShaderModule(device, &info, nullptr, &module); r != VK_SUCCESS) {
    return VkFailed("vkCreateShaderModule", r);
  }
  return module;
}

// The buffer's handover between the server's API and this queue family: `to_us` takes it
// before the vertex input reads it, else gives it back after.
VkBufferMemoryBarrier ExternalHandover(VkBuffer buffer, uint32_t family, bool to_us) {
  const VkAccessFlags read = VK_ACCESS_VERTEX_ATTRIBUTE_READ_BIT, none = 0;
  return {.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER,
          .srcAccessMask = to_us ? none : read,
          .dstAccessMask = to_us ? read : none,
          .srcQueueFamilyIndex = to_us ? VK_QUEUE_FAMILY_EXTERNAL : family,
          .dstQueueFamilyIndex = to_us ? family : VK_QUEUE_FAMILY_EXTERNAL,
          .buffer = buffer,
          .offset = 0,
          .size = VK_WHOLE_SIZE};
}

// The pipeline's fixed-function states: positions and normals from their own offsets of
// the buffer (x y z float32 each), the whole image, both faces, depth test.
struct FixedStates {
  FixedStates(VkPrimitiveTopology topology, uint32_t width, uint32_t height)
      : viewport{0, 0, static_cast<float>(width), static_cast<float>(height), 0, 1},
        scissor{{0, 0}, {width, height}} {
    assembly.topology = topology;
  }
  FixedStates(const FixedStates&) = delete;  // the infos point into it
  FixedStates& operator=(const FixedStates&) = delete;
  const VkVertexInputBindingDescription bindings[2] = {{0, 12, VK_VERTEX_INPUT_RATE_VERTEX},
                                                       {1, 12, VK_VERTEX_INPUT_RATE_VERTEX}};
  const VkVertexInputAttributeDescription attributes[2] = {{0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
                                                           {1, 1, VK_FORMAT_R32G32B32_SFLOAT, 0}};
  const VkPipelineVertexInputStateCreateInfo input{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
      .vertexBindingDescriptionCount = 2,
      .pVertexBindingDescriptions = bindings,
      .vertexAttributeDescriptionCount = 2,
      .pVertexAttributeDescriptions = attributes};
  VkPipelineInputAssemblyStateCreateInfo assembly{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  const VkViewport viewport;
  const VkRect2D scissor;
  const VkPipelineViewportStateCreateInfo viewports{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
      .viewportCount = 1,
      .pViewports = &viewport,
      .scissorCount = 1,
      .pScissors = &scissor};
  const VkPipelineRasterizationStateCreateInfo raster{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
      .polygonMode = VK_POLYGON_MODE_FILL,
      .cullMode = VK_CULL_MODE_NONE,  // both sides: a skinned limb may turn inside out
      .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
      .lineWidth = 1};
  const VkPipelineMultisampleStateCreateInfo multisample{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
      .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT};
  const VkPipelineDepthStencilStateCreateInfo depth{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
      .depthTestEnable = VK_TRUE,
      .depthWriteEnable = VK_TRUE,
      .depthCompareOp = VK_COMPARE_OP_LESS};
  const VkPipelineColorBlendAttachmentState blend{.colorWriteMask = 0xF};
  const VkPipelineColorBlendStateCreateInfo blending{
      .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
      .attachmentCount = 1,
      .pAttachments = &blend};
};

}  // namespace

Transform FrontView(const std::array<float, 3>& lo, const std::array<float, 3>& hi, uint32_t width,
                    uint32_t height) {
  const float margin = 1.08f;
  const float cx = (lo[0] + hi[0]) / 2, cy = (lo[1] + hi[1]) / 2;
  const float sx = std::max(hi[0] - lo[0], 1e-6f) * margin / 2;
  const float sy = std::max(hi[1] - lo[1], 1e-6f) * margin / 2;
  const float aspect = static_cast<float>(width) / static_cast<float>(height);
  // The larger half-extent, in the image's proportions, fills its side.
  const float half_h = std::max(sy, sx / aspect), half_w = half_h * aspect;
  const float depth = std::max(hi[2] - lo[2], 1e-6f) * margin;
  Transform t = {};
  t[0] = 1 / half_w;   // x
  t[5] = -1 / half_h;  // y up: Vulkan's clip y points down
  t[10] = -1 / depth;  // the largest z nearest (depth 0)
  t[12] = -cx / half_w;
  t[13] = cy / half_h;
  t[14] = (hi[2] + (depth - (hi[2] - lo[2])) / 2) / depth;
  t[15] = 1;
  return t;
}

Transform FrontViewOf(std::span<const double> positions, uint32_t width, uint32_t height) {
  std::array<float, 3> lo = {1e30f, 1e30f, 1e30f}, hi = {-1e30f, -1e30f, -1e30f};
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const auto x = static_cast<float>(positions[i]);
    lo[i % 3] = std::min(lo[i % 3], x);
    hi[i % 3] = std::max(hi[i % 3], x);
  }
  return FrontView(lo, hi, width, height);
}

Result<std::unique_ptr<VertexRenderer>> VertexRenderer::Create(const VulkanDevice& device,
                                                               uint32_t width, uint32_t height) {
  if (width == 0 || height == 0 || width > 8192 || height > 8192) {
    return InvalidArgument(fmt::format("image of {} x {}: 1 to 8192 pixels a side", width, height));
  }
  std::unique_ptr<VertexRenderer> r(new VertexRenderer(device, width, height));
  if (Status s = r->CreateTargets(); !s.ok()) return s;
  if (Status s = r->CreatePipeline(VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, &r->triangles_); !s.ok()) {
    return s;
  }
  if (Status s = r->CreatePipeline(VK_PRIMITIVE_TOPOLOGY_POINT_LIST, &r->points_); !s.ok()) {
    return s;
  }
  if (Status s = r->CreateReadBack(); !s.ok()) return s;
  return r;
}

void VertexRenderer::DestroyImage(Image& image) {
  VkDevice d = device_.device();
  if (image.view != VK_NULL_HANDLE) vkDestroyImageView(d, image.view, nullptr);
  if (image.image != VK_NULL_HANDLE) vkDestroyImage(d, image.image, nullptr);
  if (image.memory != VK_NULL_HANDLE) vkFreeMemory(d, image.memory, nullptr);
}

VertexRenderer::~VertexRenderer() {
  VkDevice d = device_.device();
  vkDeviceWaitIdle(d);
  if (fence_ != VK_NULL_HANDLE) vkDestroyFence(d, fence_, nullptr);
  if (pool_ != VK_NULL_HANDLE) vkDestroyCommandPool(d, pool_, nullptr);
  if (pixels_ != VK_NULL_HANDLE) vkDestroyBuffer(d, pixels_, nullptr);
  if (pixels_memory_ != VK_NULL_HANDLE) vkFreeMemory(d, pixels_memory_, nullptr);
  if (triangles_ != VK_NULL_HANDLE) vkDestroyPipeline(d, triangles_, nullptr);
  if (points_ != VK_NULL_HANDLE) vkDestroyPipeline(d, points_, nullptr);
  if (layout_ != VK_NULL_HANDLE) vkDestroyPipelineLayout(d, layout_, nullptr);
  if (framebuffer_ != VK_NULL_HANDLE) vkDestroyFramebuffer(d, framebuffer_, nullptr);
  if (render_pass_ != VK_NULL_HANDLE) vkDestroyRenderPass(d, render_pass_, nullptr);
  DestroyImage(color_);
  DestroyImage(depth_);
}

Status VertexRenderer::CreateImage(VkFormat format, VkImageUsageFlags usage,
                                   VkImageAspectFlags aspect, Image* image) {
  VkDevice d = device_.device();
  VkImageCreateInfo info{.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                         .imageType = VK_IMAGE_TYPE_2D,
                         .format = format,
                         .extent = {width_, height_, 1},
                         .mipLevels = 1,
                         .arrayLayers = 1,
                         .samples = VK_SAMPLE_COUNT_1_BIT,
                         .tiling = VK_IMAGE_TILING_OPTIMAL,
                         .usage = usage,
                         .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
                         .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  if (VkResult r = vkCreateImage(d, &info, nullptr, &image->image); r != VK_SUCCESS) {
    return VkFailed("vkCreateImage", r);
  }
  VkMemoryRequirements needs;
  vkGetImageMemoryRequirements(d, image->image, &needs);
  const uint32_t type =
      device_.MemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (type == UINT32_MAX) return FailedPrecondition("no device-local memory type for an image");
  VkMemoryAllocateInfo allocate{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .allocationSize = needs.size,
                                .memoryTypeIndex = type};
  if (VkResult r = vkAllocateMemory(d, &allocate, nullptr, &image->memory); r != VK_SUCCESS) {
    return VkFailed("vkAllocateMemory(image)", r);
  }
  vkBindImageMemory(d, image->image, image->memory, 0);
  VkImageViewCreateInfo view{.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
                             .image = image->image,
                             .viewType = VK_IMAGE_VIEW_TYPE_2D,
                             .format = format,
                             .subresourceRange = {aspect, 0, 1, 0, 1}};
  if (VkResult r = vkCreateImageView(d, &view, nullptr, &image->view); r != VK_SUCCESS) {
    return VkFailed("vkCreateImageView", r);
  }
  return Status::Ok();
}

Status VertexRenderer::CreateTargets() {
  if (Status s = CreateImage(kColorFormat,
                             VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT, &color_);
      !s.ok()) {
    return s;
  }
  if (Status s = CreateImage(kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                             VK_IMAGE_ASPECT_DEPTH_BIT, &depth_);
      !s.ok()) {
    return s;
  }
  if (Status s = CreateRenderPass(); !s.ok()) return s;
  const VkImageView views[] = {color_.view, depth_.view};
  VkFramebufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                               .renderPass = render_pass_,
                               .attachmentCount = 2,
                               .pAttachments = views,
                               .width = width_,
                               .height = height_,
                               .layers = 1};
  if (VkResult r = vkCreateFramebuffer(device_.device(), &info, nullptr, &framebuffer_);
      r != VK_SUCCESS) {
    return VkFailed("vkCreateFramebuffer", r);
  }
  return Status::Ok();
}

Status VertexRenderer::CreateRenderPass() {
  const VkAttachmentDescription attachments[] = {
      {.format = kColorFormat,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
       .finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL},
      {.format = kDepthFormat,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
       .finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL}};
  const VkAttachmentReference color{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  const VkAttachmentReference depth{1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  const VkSubpassDescription subpass{.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                     .colorAttachmentCount = 1,
                                     .pColorAttachments = &color,
                                     .pDepthStencilAttachment = &depth};
  // The copy to the host reads what the pass wrote.
  const VkSubpassDependency after{.srcSubpass = 0,
                                  .dstSubpass = VK_SUBPASS_EXTERNAL,
                                  .srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                                  .dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT,
                                  .srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                                  .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT};
  VkRenderPassCreateInfo info{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                              .attachmentCount = 2,
                              .pAttachments = attachments,
                              .subpassCount = 1,
                              .pSubpasses = &subpass,
                              .dependencyCount = 1,
                              .pDependencies = &after};
  if (VkResult r = vkCreateRenderPass(device_.device(), &info, nullptr, &render_pass_);
      r != VK_SUCCESS) {
    return VkFailed("vkCreateRenderPass", r);
  }
  return Status::Ok();
}

Status VertexRenderer::CreatePipeline(VkPrimitiveTopology topology, VkPipeline* pipeline) {
  VkDevice d = device_.device();
  if (layout_ == VK_NULL_HANDLE) {
    const VkPushConstantRange push{VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                                   sizeof(PushConstants)};
    VkPipelineLayoutCreateInfo info{.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                    .pushConstantRangeCount = 1,
                                    .pPushConstantRanges = &push};
    if (VkResult r = vkCreatePipelineLayout(d, &info, nullptr, &layout_); r != VK_SUCCESS) {
      return VkFailed("vkCreatePipelineLayout", r);
    }
  }
  Result<VkShaderModule> vert = Shader(d, kDrawVert, sizeof(kDrawVert));
  if (!vert.ok()) return vert.status();
  Result<VkShaderModule> frag = Shader(d, kDrawFrag, sizeof(kDrawFrag));
  if (!frag.ok()) {
    vkDestroyShaderModule(d, *vert, nullptr);
    return frag.status();
  }
  const VkPipelineShaderStageCreateInfo stages[] = {
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_VERTEX_BIT,
       .module = *vert,
       .pName = "main"},
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
       .module = *frag,
       .pName = "main"}};
  const FixedStates fixed(topology, width_, height_);
  VkGraphicsPipelineCreateInfo info{.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                    .stageCount = 2,
                                    .pStages = stages,
                                    .pVertexInputState = &fixed.input,
                                    .pInputAssemblyState = &fixed.assembly,
                                    .pViewportState = &fixed.viewports,
                                    .pRasterizationState = &fixed.raster,
                                    .pMultisampleState = &fixed.multisample,
                                    .pDepthStencilState = &fixed.depth,
                                    .pColorBlendState = &fixed.blending,
                                    .layout = layout_,
                                    .renderPass = render_pass_};
  VkResult r = vkCreateGraphicsPipelines(d, VK_NULL_HANDLE, 1, &info, nullptr, pipeline);
  vkDestroyShaderModule(d, *vert, nullptr);
  vkDestroyShaderModule(d, *frag, nullptr);
  return r == VK_SUCCESS ? Status::Ok() : VkFailed("vkCreateGraphicsPipelines", r);
}

Status VertexRenderer::CreateReadBack() {
  VkDevice d = device_.device();
  VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                          .size = 4ull * width_ * height_,
                          .usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                          .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
  if (VkResult r = vkCreateBuffer(d, &info, nullptr, &pixels_); r != VK_SUCCESS) {
    return VkFailed("vkCreateBuffer(pixels)", r);
  }
  VkMemoryRequirements needs;
  vkGetBufferMemoryRequirements(d, pixels_, &needs);
  const uint32_t type =
      device_.MemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                   VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  if (type == UINT32_MAX) return FailedPrecondition("no host-visible coherent memory type");
  VkMemoryAllocateInfo allocate{.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .allocationSize = needs.size,
                                .memoryTypeIndex = type};
  if (VkResult r = vkAllocateMemory(d, &allocate, nullptr, &pixels_memory_); r != VK_SUCCESS) {
    return VkFailed("vkAllocateMemory(pixels)", r);
  }
  vkBindBufferMemory(d, pixels_, pixels_memory_, 0);
  if (VkResult r = vkMapMemory(d, pixels_memory_, 0, info.size, 0, &mapped_); r != VK_SUCCESS) {
    return VkFailed("vkMapMemory(pixels)", r);
  }
  VkCommandPoolCreateInfo pool{.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                               .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                               .queueFamilyIndex = device_.queue_family()};
  if (VkResult r = vkCreateCommandPool(d, &pool, nullptr, &pool_); r != VK_SUCCESS) {
    return VkFailed("vkCreateCommandPool", r);
  }
  VkCommandBufferAllocateInfo command{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                      .commandPool = pool_,
                                      .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                      .commandBufferCount = 1};
  vkAllocateCommandBuffers(d, &command, &commands_);
  VkFenceCreateInfo fence{.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  if (VkResult r = vkCreateFence(d, &fence, nullptr, &fence_); r != VK_SUCCESS) {
    return VkFailed("vkCreateFence", r);
  }
  return Status::Ok();
}

void VertexRenderer::RecordDraw(const DrawSource& source) {
  const VkBufferMemoryBarrier take =
      ExternalHandover(source.vertices, device_.queue_family(), /*to_us=*/true);
  if (source.external) {
    vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                         VK_PIPELINE_STAGE_VERTEX_INPUT_BIT, 0, 0, nullptr, 1, &take, 0, nullptr);
  }
  const VkClearValue clears[2] = {
      {.color = {{kBackground[0] / 255.0f, kBackground[1] / 255.0f, kBackground[2] / 255.0f, 1}}},
      {.depthStencil = {1, 0}}};
  VkRenderPassBeginInfo begin{.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                              .renderPass = render_pass_,
                              .framebuffer = framebuffer_,
                              .renderArea = {{0, 0}, {width_, height_}},
                              .clearValueCount = 2,
                              .pClearValues = clears};
  vkCmdBeginRenderPass(commands_, &begin, VK_SUBPASS_CONTENTS_INLINE);
  const bool indexed = source.indices != VK_NULL_HANDLE;
  vkCmdBindPipeline(commands_, VK_PIPELINE_BIND_POINT_GRAPHICS, indexed ? triangles_ : points_);
  PushConstants push{};
  std::memcpy(push.transform, source.transform.data(), sizeof(push.transform));
  push.point_size = device_.large_points() ? source.point_size : 1.0f;
  push.has_normals = source.normals ? 1.0f : 0.0f;
  vkCmdPushConstants(commands_, layout_, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT,
                     0, sizeof(push), &push);
  // Without normals the positions stand in for them (the shader does not shade then).
  const VkBuffer buffers[] = {source.vertices, source.vertices};
  const VkDeviceSize offsets[] = {source.positions_offset,
                                  source.normals ? source.normals_offset : source.positions_offset};
  vkCmdBindVertexBuffers(commands_, 0, 2, buffers, offsets);
  if (indexed) {
    vkCmdBindIndexBuffer(commands_, source.indices, 0, VK_INDEX_TYPE_UINT32);
    vkCmdDrawIndexed(commands_, source.index_count, 1, 0, 0, 0);
  } else {
    vkCmdDraw(commands_, source.vertex_count, 1, 0, 0);
  }
  vkCmdEndRenderPass(commands_);
  if (source.external) {  // back to the server for its next frame
    const VkBufferMemoryBarrier give =
        ExternalHandover(source.vertices, device_.queue_family(), /*to_us=*/false);
    vkCmdPipelineBarrier(commands_, VK_PIPELINE_STAGE_VERTEX_INPUT_BIT,
                         VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 1, &give, 0, nullptr);
  }
  const VkBufferImageCopy copy{.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                               .imageExtent = {width_, height_, 1}};
  vkCmdCopyImageToBuffer(commands_, color_.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, pixels_, 1,
                         &copy);
}

Result<std::span<const uint8_t>> VertexRenderer::Draw(const DrawSource& source) {
  vkResetCommandBuffer(commands_, 0);
  VkCommandBufferBeginInfo begin{.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                 .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
  vkBeginCommandBuffer(commands_, &begin);
  RecordDraw(source);
  vkEndCommandBuffer(commands_);
  const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_VERTEX_INPUT_BIT;
  VkSubmitInfo submit{.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                      .waitSemaphoreCount = source.wait != VK_NULL_HANDLE ? 1u : 0u,
                      .pWaitSemaphores = &source.wait,
                      .pWaitDstStageMask = &wait_stage,
                      .commandBufferCount = 1,
                      .pCommandBuffers = &commands_};
  vkResetFences(device_.device(), 1, &fence_);
  if (VkResult r = vkQueueSubmit(device_.queue(), 1, &submit, fence_); r != VK_SUCCESS) {
    return VkFailed("vkQueueSubmit(draw)", r);
  }
  if (VkResult r = vkWaitForFences(device_.device(), 1, &fence_, VK_TRUE, kFenceTimeoutNs);
      r != VK_SUCCESS) {
    return r == VK_TIMEOUT ? DeadlineExceeded(
                                 "the draw did not finish within 20 s: was the "
                                 "server's semaphore signalled?")
                           : VkFailed("vkWaitForFences(draw)", r);
  }
  return std::span<const uint8_t>(static_cast<const uint8_t*>(mapped_), 4ull * width_ * height_);
}

}  // namespace skinserve::gpu_region
