// skinserve-gpu-region's renderer (--draw) on the CPU's Vulkan (Mesa's lavapipe, from
// scripts/install-deps.sh): a known mesh filled by the test in a vertex buffer laid out as
// a GPU region lays it (positions, then normals at the next multiple of 64) drawn through
// the same code as the skinned character. Pixels well inside a triangle show it, pixels
// well outside show the background, the nearer of two overlapping triangles wins (depth),
// each shaded by its normal; points without an index buffer; the PNG written and read back.
// The server is not involved: its GPU run is scripts/gpu-region-test.sh.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "draw_check.h"
#include "png_file.h"
#include "triangle_check.h"
#include "vertex_renderer.h"
#include "vulkan_device.h"

namespace skinserve::gpu_region {
namespace {

constexpr uint32_t kWidth = 96, kHeight = 64;

// A host-visible buffer of `bytes` for vertices or indices, filled from `data`.
class HostBuffer {
 public:
  HostBuffer(const VulkanDevice& device, const void* data, std::size_t bytes,
             VkBufferUsageFlags usage)
      : device_(device) {
    VkBufferCreateInfo info{.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                            .size = bytes,
                            .usage = usage,
                            .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
    EXPECT_EQ(vkCreateBuffer(device.device(), &info, nullptr, &buffer_), VK_SUCCESS);
    VkMemoryRequirements needs;
    vkGetBufferMemoryRequirements(device.device(), buffer_, &needs);
    VkMemoryAllocateInfo allocate{
        .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
        .allocationSize = needs.size,
        .memoryTypeIndex =
            device.MemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                        VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)};
    EXPECT_EQ(vkAllocateMemory(device.device(), &allocate, nullptr, &memory_), VK_SUCCESS);
    vkBindBufferMemory(device.device(), buffer_, memory_, 0);
    void* mapped = nullptr;
    EXPECT_EQ(vkMapMemory(device.device(), memory_, 0, bytes, 0, &mapped), VK_SUCCESS);
    std::memcpy(mapped, data, bytes);
    vkUnmapMemory(device.device(), memory_);
  }
  ~HostBuffer() {
    vkDestroyBuffer(device_.device(), buffer_, nullptr);
    vkFreeMemory(device_.device(), memory_, nullptr);
  }
  VkBuffer get() const { return buffer_; }

 private:
  const VulkanDevice& device_;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
};

struct Vulkan {
  std::unique_ptr<VulkanDevice> device;
  std::unique_ptr<VertexRenderer> renderer;
};

Vulkan& TestVulkan() {
  static Vulkan vk;
  if (vk.device == nullptr) {
    auto device = VulkanDevice::Create(-1, /*memory_fd=*/false, /*semaphore_fd=*/false);
    if (!device.ok()) {
      ADD_FAILURE() << device.status().ToString()
                    << " (the CPU's Vulkan is Mesa's lavapipe: mesa-vulkan-drivers)";
      std::abort();
    }
    vk.device = std::move(device).value();
    auto renderer = VertexRenderer::Create(*vk.device, kWidth, kHeight);
    if (!renderer.ok()) {
      ADD_FAILURE() << renderer.status().ToString();
      std::abort();
    }
    vk.renderer = std::move(renderer).value();
  }
  return vk;
}

// The shade the fragment shader gives a normal, 0-255 per channel (its formula, restated).
std::array<double, 3> Shade(double nx, double ny, double nz) {
  const double l = std::sqrt(0.16 + 0.36 + 0.49);
  const double n = std::sqrt(nx * nx + ny * ny + nz * nz);
  const double s = 0.35 + 0.65 * std::abs((-0.4 * nx + 0.6 * ny + 0.7 * nz) / (l * n));
  return {0.90 * s * 255, 0.62 * s * 255, 0.36 * s * 255};
}

// The scene in the box [-1, 1]^3: triangle A in front (z = 0.5, facing the viewer) over
// the upper left, triangle B behind it (z = -0.5, facing +x) over the right half, the two
// overlapping in the middle.
struct Scene {
  std::vector<float> bytes;  // positions at 0, normals at 64 bytes (16 floats) past them
  uint64_t normals_offset = 0;
  std::vector<uint32_t> indices = {0, 1, 2, 3, 4, 5};
};

Scene TwoTriangles() {
  const float positions[] = {-0.9f, 0.9f, 0.5f,  0.3f, 0.9f, 0.5f,  -0.9f, -0.3f, 0.5f,
                             -0.2f, 0.8f, -0.5f, 0.9f, 0.8f, -0.5f, 0.9f,  -0.9f, -0.5f};
  const float normals[] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 1, 0, 0};
  Scene s;
  s.normals_offset = 128;  // 72 bytes of positions, rounded up to 64
  s.bytes.assign(s.normals_offset / 4 + 18, 0.0f);
  std::memcpy(s.bytes.data(), positions, sizeof(positions));
  std::memcpy(s.bytes.data() + s.normals_offset / 4, normals, sizeof(normals));
  return s;
}

// Signed distance in pixels from pixel (x, y)'s centre to triangle (a, b, c) in image
// coordinates: > 0 inside.
double Inside(double x, double y, const double* a, const double* b, const double* c) {
  double d = 1e9;
  const double* v[] = {a, b, c};
  const double area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  for (int i = 0; i < 3; ++i) {
    const double* p = v[i];
    const double* q = v[(i + 1) % 3];
    const double ex = q[0] - p[0], ey = q[1] - p[1];
    const double cross = ex * (y - p[1]) - ey * (x - p[0]);
    d = std::min(d, (area > 0 ? cross : -cross) / std::hypot(ex, ey));
  }
  return d;
}

// Model x y to image pixels for the front view of [-1, 1]^3 in kWidth x kHeight: the box's
// height (2, with the 8% margin) fills the image's height, centred, y up.
void ToPixel(double x, double y, double* out) {
  const double half = 1.08, scale = kHeight / (2 * half);
  out[0] = kWidth / 2.0 + x * scale;
  out[1] = kHeight / 2.0 - y * scale;
}

const uint8_t* Pixel(std::span<const uint8_t> rgba, uint32_t x, uint32_t y) {
  return rgba.data() + 4ull * (y * kWidth + x);
}

bool Near(const uint8_t* p, const std::array<double, 3>& want) {
  for (int c = 0; c < 3; ++c) {
    if (std::abs(p[c] - want[c]) > 2.5) return false;
  }
  return true;
}

TEST(VertexRendererTest, TrianglesCoverTheirPixelsNearestInFront) {
  Vulkan& vk = TestVulkan();
  const Scene scene = TwoTriangles();
  HostBuffer vertices(*vk.device, scene.bytes.data(), scene.bytes.size() * 4,
                      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  HostBuffer indices(*vk.device, scene.indices.data(), scene.indices.size() * 4,
                     VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  auto pixels =
      vk.renderer->Draw({.vertices = vertices.get(),
                         .normals_offset = scene.normals_offset,
                         .normals = true,
                         .vertex_count = 6,
                         .indices = indices.get(),
                         .index_count = 6,
                         .transform = FrontView({-1, -1, -1}, {1, 1, 1}, kWidth, kHeight)});
  ASSERT_TRUE(pixels.ok()) << pixels.status().ToString();
  double a[3][2], b[3][2];
  const float* p = scene.bytes.data();
  for (int i = 0; i < 3; ++i) {
    ToPixel(p[3 * i], p[3 * i + 1], a[i]);
    ToPixel(p[9 + 3 * i], p[9 + 3 * i + 1], b[i]);
  }
  const auto front = Shade(0, 0, 1), back = Shade(1, 0, 0);
  const auto& bg = VertexRenderer::kBackground;
  int in_a = 0, in_b_only = 0, outside = 0;
  for (uint32_t y = 0; y < kHeight; ++y) {
    for (uint32_t x = 0; x < kWidth; ++x) {
      const double da = Inside(x + 0.5, y + 0.5, a[0], a[1], a[2]);
      const double db = Inside(x + 0.5, y + 0.5, b[0], b[1], b[2]);
      const uint8_t* px = Pixel(*pixels, x, y);
      if (da > 1.5) {  // A, in front, wherever it is (over B too)
        EXPECT_TRUE(Near(px, front)) << "pixel " << x << "," << y << " should show triangle A";
        ++in_a;
      } else if (db > 1.5 && da < -1.5) {
        EXPECT_TRUE(Near(px, back)) << "pixel " << x << "," << y << " should show triangle B";
        ++in_b_only;
      } else if (da < -1.5 && db < -1.5) {
        EXPECT_TRUE(std::equal(px, px + 4, bg.begin()))
            << "pixel " << x << "," << y << " should be background";
        ++outside;
      }
    }
  }
  // The scene has all three kinds, and A covers part of B.
  EXPECT_GT(in_a, 300);
  EXPECT_GT(in_b_only, 300);
  EXPECT_GT(outside, 1000);
}

// --mesh's picture check (CheckTrianglePicture) on two triangles that mostly overlap, A in
// front (facing the viewer), B behind (facing +x): the picture is theirs; the same
// triangles with their depths swapped (B in front) are not, though their outline is the
// same: the overlap shows A's normal, not B's.
TEST(VertexRendererTest, TheTriangleCheckSeesWhichTriangleIsInFront) {
  Vulkan& vk = TestVulkan();
  const std::vector<double> positions = {-0.9, 0.9, 0.5,  0.9, 0.9, 0.5,  -0.9, -0.9, 0.5,
                                         -0.8, 0.8, -0.5, 0.9, 0.8, -0.5, 0.9,  -0.9, -0.5};
  const std::vector<double> normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 1, 0, 0};
  std::vector<float> bytes(32 + 18, 0.0f);  // normals at 128: 72 bytes rounded up to 64
  std::copy(positions.begin(), positions.end(), bytes.begin());
  std::copy(normals.begin(), normals.end(), bytes.begin() + 32);
  const std::vector<uint32_t> triangles = {0, 1, 2, 3, 4, 5};
  HostBuffer vertices(*vk.device, bytes.data(), bytes.size() * 4,
                      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  HostBuffer indices(*vk.device, triangles.data(), 24, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
  const Transform t = FrontView({-1, -1, -1}, {1, 1, 1}, kWidth, kHeight);
  auto pixels = vk.renderer->Draw({.vertices = vertices.get(),
                                   .normals_offset = 128,
                                   .normals = true,
                                   .vertex_count = 6,
                                   .indices = indices.get(),
                                   .index_count = 6,
                                   .transform = t});
  ASSERT_TRUE(pixels.ok()) << pixels.status().ToString();
  const TrianglePictureCheck check =
      CheckTrianglePicture(*pixels, kWidth, kHeight, positions, normals, triangles, t);
  EXPECT_TRUE(check.ok()) << check.ToString();
  EXPECT_GT(check.shaded_pixels, 1000u) << check.ToString();
  std::vector<double> swapped_depths = positions;
  for (std::size_t i = 2; i < positions.size(); i += 3) swapped_depths[i] = -positions[i];
  const TrianglePictureCheck swapped =
      CheckTrianglePicture(*pixels, kWidth, kHeight, swapped_depths, normals, triangles, t);
  EXPECT_FALSE(swapped.ok()) << swapped.ToString();
  EXPECT_LT(swapped.shade_matches, 0.8) << swapped.ToString();
  EXPECT_EQ(swapped.inside_drawn, 1.0) << swapped.ToString();  // the outline still matches
}

TEST(VertexRendererTest, PointsWithoutIndicesLandWhereTheReferenceProjects) {
  Vulkan& vk = TestVulkan();
  std::vector<float> points;
  std::vector<double> reference;
  for (int i = 0; i < 40; ++i) {  // a spiral, no normals
    const double t = i / 40.0;
    const double x = 0.9 * t * std::cos(12 * t), y = 0.9 * t * std::sin(12 * t), z = t - 0.5;
    for (double c : {x, y, z}) {
      points.push_back(static_cast<float>(c));
      reference.push_back(c);
    }
  }
  HostBuffer vertices(*vk.device, points.data(), points.size() * 4,
                      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  const Transform t = FrontView({-1, -1, -1}, {1, 1, 1}, kWidth, kHeight);
  auto pixels = vk.renderer->Draw(
      {.vertices = vertices.get(), .vertex_count = 40, .transform = t, .point_size = 1});
  ASSERT_TRUE(pixels.ok()) << pixels.status().ToString();
  const PictureCheck check = CheckPicture(*pixels, kWidth, kHeight, reference, t, 1);
  EXPECT_TRUE(check.ok()) << check.ToString();
  EXPECT_GE(check.drawn_pixels, 30u) << check.ToString();
  // The same points mirrored (y flipped) are not what was drawn.
  for (std::size_t i = 1; i < reference.size(); i += 3) reference[i] = -reference[i];
  EXPECT_FALSE(CheckPicture(*pixels, kWidth, kHeight, reference, t, 1).ok());
}

TEST(VertexRendererTest, PngHoldsThePixels) {
  Vulkan& vk = TestVulkan();
  const Scene scene = TwoTriangles();
  HostBuffer vertices(*vk.device, scene.bytes.data(), scene.bytes.size() * 4,
                      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  auto pixels =
      vk.renderer->Draw({.vertices = vertices.get(),
                         .vertex_count = 6,
                         .transform = FrontView({-1, -1, -1}, {1, 1, 1}, kWidth, kHeight)});
  ASSERT_TRUE(pixels.ok());
  const std::vector<uint8_t> drawn(pixels->begin(), pixels->end());
  const std::string path =
      (std::filesystem::temp_directory_path() / "skinserve-vertex-renderer-test.png").string();
  ASSERT_TRUE(WritePng(path, drawn, kWidth, kHeight).ok());
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&image, path.c_str())) << image.message;
  image.format = PNG_FORMAT_RGBA;
  std::vector<uint8_t> read(PNG_IMAGE_SIZE(image));
  ASSERT_TRUE(png_image_finish_read(&image, nullptr, read.data(), 0, nullptr)) << image.message;
  EXPECT_EQ(image.width, kWidth);
  EXPECT_EQ(image.height, kHeight);
  EXPECT_EQ(read, drawn);
  std::filesystem::remove(path);
  EXPECT_FALSE(WritePng("/nonexistent-dir/x.png", drawn, kWidth, kHeight).ok());
}

}  // namespace
}  // namespace skinserve::gpu_region
