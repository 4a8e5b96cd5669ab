// skinserve-gpu-region's --mesh picture on the CPU's Vulkan (Mesa's lavapipe): CesiumMan at
// its clip's middle, skinned on the CPU by the float64 reference (no server), laid out in a
// vertex buffer as a GPU region lays it (float32 positions, normals at the region layout's
// offset), drawn with its index buffer through the renderer and judged by the check --draw
// uses (JudgePicture: CheckTrianglePicture). The picture is covered where the character is
// and background elsewhere; the check fails on the picture mirrored (left-right or upside
// down), on a wrong pose, and on a picture missing half of the triangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "draw_check.h"
#include "host_buffer.h"
#include "png_file.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"
#include "triangle_check.h"
#include "vertex_renderer.h"
#include "vulkan_device.h"
#include "workload.h"

namespace skinserve::gpu_region {
namespace {

constexpr uint32_t kSize = 256;

struct Drawn {
  std::vector<uint8_t> pixels;
  ReferenceFrame reference;
  Transform transform;
};

class CharacterDrawTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto w = load::MakeGltfWorkload(SKINSERVE_SOURCE_DIR "/tests/assets/gltf/CesiumMan.glb", -1,
                                    /*normals=*/true);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    workload_ = new load::Workload(std::move(w).value());
    auto device = VulkanDevice::Create(-1, /*memory_fd=*/false, /*semaphore_fd=*/false);
    ASSERT_TRUE(device.ok()) << device.status().ToString()
                             << " (the CPU's Vulkan is Mesa's lavapipe: mesa-vulkan-drivers)";
    device_ = std::move(device).value().release();
    auto renderer = VertexRenderer::Create(*device_, kSize, kSize);
    ASSERT_TRUE(renderer.ok()) << renderer.status().ToString();
    renderer_ = std::move(renderer).value().release();
  }
  static void TearDownTestSuite() {
    delete renderer_;
    delete device_;
    delete workload_;
  }
  static uint32_t Middle() { return static_cast<uint32_t>(workload_->palettes.size() / 2); }

  // Frame `frame` skinned by the reference, drawn with the first `triangles` of the index
  // buffer (all: -1), framed on the reference's bounds as --draw frames it.
  static Drawn Draw(uint32_t frame, int64_t triangles = -1) {
    const load::Workload& w = *workload_;
    Drawn d{.reference = ReferenceSkin(*w.mesh, w.Palette(frame), w.Morph(frame))};
    d.transform = FrontViewOf(d.reference.positions, kSize, kSize);
    const wire::RegionLayout layout =
        wire::LayoutInRegion(0, w.vertices, 1, VertexEncoding::kFloat32, /*normals=*/true);
    std::vector<float> region(layout.end_offset / sizeof(float), 0.0f);
    for (std::size_t i = 0; i < d.reference.positions.size(); ++i) {
      region[layout.positions_offset / 4 + i] = static_cast<float>(d.reference.positions[i]);
      region[layout.normals_offset / 4 + i] = static_cast<float>(d.reference.normals[i]);
    }
    auto vertices = HostBuffer::Create(*device_, region.data(), region.size() * sizeof(float),
                                       VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
    auto indices = HostBuffer::Create(*device_, w.indices.data(), w.indices.size() * 4,
                                      VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
    EXPECT_TRUE(vertices.ok() && indices.ok());
    const auto count = static_cast<uint32_t>(triangles < 0 ? w.indices.size() : 3 * triangles);
    auto pixels = renderer_->Draw({.vertices = (*vertices)->buffer(),
                                   .positions_offset = layout.positions_offset,
                                   .normals_offset = layout.normals_offset,
                                   .normals = true,
                                   .vertex_count = w.vertices,
                                   .indices = (*indices)->buffer(),
                                   .index_count = count,
                                   .transform = d.transform});
    EXPECT_TRUE(pixels.ok()) << pixels.status().ToString();
    if (pixels.ok()) d.pixels.assign(pixels->begin(), pixels->end());
    return d;
  }

  static PictureVerdict Judge(const std::vector<uint8_t>& pixels, const ReferenceFrame& reference,
                              const Transform& transform) {
    return JudgePicture(pixels, kSize, kSize, reference.positions, reference.normals,
                        workload_->indices, transform);
  }

  static load::Workload* workload_;
  static VulkanDevice* device_;
  static VertexRenderer* renderer_;
};

load::Workload* CharacterDrawTest::workload_ = nullptr;
VulkanDevice* CharacterDrawTest::device_ = nullptr;
VertexRenderer* CharacterDrawTest::renderer_ = nullptr;

bool IsBackground(const std::vector<uint8_t>& pixels, uint32_t x, uint32_t y) {
  const uint8_t* p = pixels.data() + 4ull * (y * kSize + x);
  return std::equal(p, p + 4, VertexRenderer::kBackground.begin());
}

TEST_F(CharacterDrawTest, TheMiddlePoseDrawsAsTheReference) {
  const Drawn d = Draw(Middle());
  ASSERT_EQ(d.pixels.size(), 4ull * kSize * kSize);
  const TrianglePictureCheck check =
      CheckTrianglePicture(d.pixels, kSize, kSize, d.reference.positions, d.reference.normals,
                           workload_->indices, d.transform);
  EXPECT_TRUE(check.ok()) << check.ToString();
  EXPECT_TRUE(Judge(d.pixels, d.reference, d.transform).ok);
  // SKINSERVE_DRAW_TEST_PNG=FILE: the picture, to look at.
  if (const char* png = std::getenv("SKINSERVE_DRAW_TEST_PNG"); png != nullptr) {
    EXPECT_TRUE(WritePng(png, d.pixels, kSize, kSize).ok());
  }
  // A character, not a speck or a full frame: framed on its bounds, it fills a fair part
  // of the picture, and the corners (outside the 8% margin) are background.
  EXPECT_GT(check.inside_pixels, kSize * kSize / 20) << check.ToString();
  EXPECT_LT(check.drawn_pixels, kSize * kSize / 2) << check.ToString();
  EXPECT_GT(check.shaded_pixels, check.inside_pixels / 2) << check.ToString();
  for (uint32_t c : {0u, kSize - 1}) {
    EXPECT_TRUE(IsBackground(d.pixels, c, 0));
    EXPECT_TRUE(IsBackground(d.pixels, c, kSize - 1));
  }
}

TEST_F(CharacterDrawTest, AMirroredPictureFails) {
  const Drawn d = Draw(Middle());
  std::vector<uint8_t> left_right(d.pixels.size()), upside_down(d.pixels.size());
  for (uint32_t y = 0; y < kSize; ++y) {
    for (uint32_t x = 0; x < kSize; ++x) {
      std::memcpy(&left_right[4ull * (y * kSize + x)],
                  &d.pixels[4ull * (y * kSize + kSize - 1 - x)], 4);
      std::memcpy(&upside_down[4ull * (y * kSize + x)],
                  &d.pixels[4ull * ((kSize - 1 - y) * kSize + x)], 4);
    }
  }
  const PictureVerdict mirrored = Judge(left_right, d.reference, d.transform);
  EXPECT_FALSE(mirrored.ok) << mirrored.summary;
  const PictureVerdict flipped = Judge(upside_down, d.reference, d.transform);
  EXPECT_FALSE(flipped.ok) << flipped.summary;
}

TEST_F(CharacterDrawTest, AWrongPoseFails) {
  // Frame 0 drawn, the middle of the clip expected (in the middle pose's framing).
  const Drawn middle = Draw(Middle());
  const Drawn first = Draw(0);
  const PictureVerdict verdict = Judge(first.pixels, middle.reference, first.transform);
  EXPECT_FALSE(verdict.ok) << verdict.summary;
}

TEST_F(CharacterDrawTest, AMissingTriangleSetFails) {
  const auto triangles = static_cast<int64_t>(workload_->indices.size() / 3);
  const Drawn half = Draw(Middle(), triangles / 2);
  const PictureVerdict verdict = Judge(half.pixels, half.reference, half.transform);
  EXPECT_FALSE(verdict.ok) << verdict.summary;
}

}  // namespace
}  // namespace skinserve::gpu_region
