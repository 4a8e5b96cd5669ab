// The camera and the renderer: images of the right size, not blank, the subject framed
// inside them, upright, shaded (smoothly with normals), nearer surfaces over farther ones
// pixel by pixel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "png_pixels.h"
#include "skinserve/render/bounds.h"
#include "skinserve/render/camera.h"
#include "skinserve/render/mesh_renderer.h"

namespace skinserve::testing {
namespace {

struct TestMesh {
  std::vector<float> positions;
  std::vector<uint32_t> indices;
};

// An axis-aligned box, faces wound counter-clockwise seen from outside (glTF's front).
TestMesh Box(glm::vec3 lo, glm::vec3 hi) {
  TestMesh m;
  for (int c = 0; c < 8; ++c) {
    m.positions.insert(m.positions.end(),
                       {(c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z});
  }
  // Quads as corner bits (x=1, y=2, z=4), counter-clockwise from outside.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  return m;
}

// A quad in the plane z = `z` facing +Z, rotated by `tilt` radians about x.
void AddQuad(TestMesh* m, float half, float z, float tilt) {
  const uint32_t base = static_cast<uint32_t>(m->positions.size() / 3);
  const float corners[4][2] = {{-half, -half}, {half, -half}, {half, half}, {-half, half}};
  for (const auto& c : corners) {
    m->positions.insert(m->positions.end(),
                        {c[0], c[1] * std::cos(tilt), z + c[1] * std::sin(-tilt)});
  }
  m->indices.insert(m->indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

render::Camera CameraFor(const TestMesh& m, int width, int height) {
  auto bounds = render::BoundsOf(m.positions);
  EXPECT_TRUE(bounds.ok()) << bounds.status().ToString();
  return render::Camera::Framing(*bounds, width, height);
}

TEST(CameraTest, FramesTheBoxInsideTheMarginAndUpright) {
  const render::Bounds box{{-0.5f, 0.0f, -0.3f}, {0.5f, 1.8f, 0.3f}};  // a standing figure
  const render::CameraOptions options;
  const render::Camera camera = render::Camera::Framing(box, 400, 300, options);
  float min_x = 1e9f, max_x = -1e9f, min_y = 1e9f, max_y = -1e9f;
  for (int c = 0; c < 8; ++c) {
    const render::Projected p =
        camera.Project({(c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y,
                        (c & 4) ? box.max.z : box.min.z});
    EXPECT_GT(p.depth, 0.0f);
    min_x = std::min(min_x, p.x), max_x = std::max(max_x, p.x);
    min_y = std::min(min_y, p.y), max_y = std::max(max_y, p.y);
  }
  // Tall box: it fills the height less the margins, centred.
  EXPECT_NEAR(min_y, 300 * options.margin, 0.01);
  EXPECT_NEAR(max_y, 300 * (1 - options.margin), 0.01);
  EXPECT_NEAR((min_x + max_x) / 2, 200, 0.01);
  EXPECT_GE(min_x, 400 * options.margin - 0.01);
  // Up is up: the head is above the feet in the image (smaller y).
  EXPECT_LT(camera.Project({0, 1.8f, 0}).y, camera.Project({0, 0, 0}).y);
  // Nearer is less deep: the camera is on the +Z side.
  EXPECT_LT(camera.Project({0, 1, 0.3f}).depth, camera.Project({0, 1, -0.3f}).depth);
}

TEST(RendererTest, PngOfTheCameraSizeShadedWithTheSilhouetteInside) {
  const TestMesh box = Box({-0.4f, 0.0f, -0.2f}, {0.4f, 1.6f, 0.2f});
  const render::Camera camera = CameraFor(box, 320, 240);
  const std::string path = ::testing::TempDir() + "render-box.png";
  render::RenderOptions options;
  options.background = {1.0f, 1.0f, 1.0f};  // exact in 8 bits, whatever Cairo's rounding
  ASSERT_TRUE(render::RenderPng(path, camera, box.positions, box.indices, options).ok());

  const Pixels png = ReadPng(path);
  ASSERT_EQ(png.width, 320);
  ASSERT_EQ(png.height, 240);
  const uint32_t background = 0xFFFFFFu;
  int covered = 0, min_x = png.width, max_x = -1, min_y = png.height, max_y = -1;
  std::set<uint32_t> colours;
  for (int y = 0; y < png.height; ++y) {
    for (int x = 0; x < png.width; ++x) {
      if (png.at(x, y) == background) continue;
      ++covered;
      colours.insert(png.at(x, y));
      min_x = std::min(min_x, x), max_x = std::max(max_x, x);
      min_y = std::min(min_y, y), max_y = std::max(max_y, y);
    }
  }
  EXPECT_GT(covered, png.width * png.height / 20) << "almost blank";
  // The silhouette is inside the image, away from the edges, and fills most of its height.
  EXPECT_GT(min_x, 0);
  EXPECT_GT(min_y, 0);
  EXPECT_LT(max_x, png.width - 1);
  EXPECT_LT(max_y, png.height - 1);
  EXPECT_GT(max_y - min_y, png.height / 2);
  // Front, side and top of the box face the light differently: several flat shades (edges
  // add blends of the 2 x 2 samples on top).
  EXPECT_GE(colours.size(), 3u);
  EXPECT_EQ(background, png.at(0, 0));
}

TEST(RendererTest, NearerTrianglesCoverFartherOnesWhateverTheirOrder) {
  TestMesh back_first, front_first, back_only;
  AddQuad(&back_first, 1.0f, 0.0f, 0.0f);
  AddQuad(&back_first, 0.3f, 0.5f, 0.9f);  // tilted: lit differently from the back quad
  AddQuad(&front_first, 0.3f, 0.5f, 0.9f);
  AddQuad(&front_first, 1.0f, 0.0f, 0.0f);
  back_only = back_first;
  back_only.indices.resize(6);
  // One camera for all three (the box of both quads).
  const render::Camera camera = CameraFor(back_first, 200, 200);
  const std::string dir = ::testing::TempDir();
  ASSERT_TRUE(
      render::RenderPng(dir + "back-first.png", camera, back_first.positions, back_first.indices)
          .ok());
  ASSERT_TRUE(
      render::RenderPng(dir + "front-first.png", camera, front_first.positions, front_first.indices)
          .ok());
  ASSERT_TRUE(
      render::RenderPng(dir + "back-only.png", camera, back_only.positions, back_only.indices)
          .ok());
  const render::Projected centre = camera.Project({0.0f, 0.0f, 0.5f});
  const int x = static_cast<int>(centre.x), y = static_cast<int>(centre.y);
  const uint32_t a = ReadPng(dir + "back-first.png").at(x, y);
  const uint32_t b = ReadPng(dir + "front-first.png").at(x, y);
  const uint32_t behind = ReadPng(dir + "back-only.png").at(x, y);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, behind) << "the front quad is not visible over the back one";
}

// Two triangles with one footprint that cross in depth: A's right half is nearer the
// camera, B's left half. A painter's sort draws one over the other everywhere; a depth
// buffer shows B on the left and A on the right, whatever the order they come in. A and B
// are separate parts: the parts of a frame share one depth buffer.
TEST(RendererTest, CrossingTrianglesAreOrderedPerPixel) {
  const std::vector<float> a = {-1, -1, -1, 1, -1, 1, 0, 1, 0};  // z = x
  const std::vector<float> b = {-1, -1, 1, 1, -1, -1, 0, 1, 0};  // z = -x
  const std::vector<uint32_t> tri = {0, 1, 2};
  render::CameraOptions front;  // straight down -z, so that left/right is -x/+x
  front.azimuth_degrees = 0;
  front.elevation_degrees = 0;
  const render::Camera camera = render::Camera::Framing({{-1, -1, -1}, {1, 1, 1}}, 200, 200, front);
  const render::RenderPart pa{a, {}, tri}, pb{b, {}, tri};
  const std::string dir = ::testing::TempDir();
  const std::vector<render::RenderPart> ab = {pa, pb}, ba = {pb, pa}, a_only = {pa}, b_only = {pb};
  for (const auto& [name, parts] : {std::pair{"ab", &ab}, std::pair{"ba", &ba},
                                    std::pair{"a", &a_only}, std::pair{"b", &b_only}}) {
    ASSERT_TRUE(render::RenderPng(dir + "cross-" + name + ".png", camera, *parts).ok()) << name;
  }
  const Pixels both = ReadPng(dir + "cross-ab.png"), reversed = ReadPng(dir + "cross-ba.png");
  const Pixels only_a = ReadPng(dir + "cross-a.png"), only_b = ReadPng(dir + "cross-b.png");
  EXPECT_EQ(both.rgb, reversed.rgb) << "the image depends on the order of the triangles";
  // Left and right of the crossing line x = 0, at the height of the footprint's middle.
  const render::Projected left = camera.Project({-0.3f, -0.5f, 0.3f});
  const render::Projected right = camera.Project({0.3f, -0.5f, 0.3f});
  const int ly = static_cast<int>(left.y), lx = static_cast<int>(left.x);
  const int ry = static_cast<int>(right.y), rx = static_cast<int>(right.x);
  ASSERT_NE(only_a.at(lx, ly), only_b.at(lx, ly)) << "A and B must be told apart by shade";
  ASSERT_NE(only_a.at(rx, ry), only_b.at(rx, ry));
  EXPECT_EQ(both.at(lx, ly), only_b.at(lx, ly)) << "left of the crossing B is nearer";
  EXPECT_EQ(both.at(rx, ry), only_a.at(rx, ry)) << "right of the crossing A is nearer";
}

// A flat square whose vertex normals turn from left to right: shaded smoothly (the shade
// changes pixel by pixel across it) with normals, one flat shade without.
TEST(RendererTest, VertexNormalsShadeSmoothly) {
  const std::vector<float> positions = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
  const float s = std::sqrt(0.5f);
  const std::vector<float> normals = {-s, 0, s, s, 0, s, s, 0, s, -s, 0, s};
  const std::vector<uint32_t> indices = {0, 1, 2, 0, 2, 3};
  render::CameraOptions front;
  front.azimuth_degrees = 0;
  front.elevation_degrees = 0;
  const render::Camera camera = render::Camera::Framing({{-1, -1, 0}, {1, 1, 0}}, 120, 120, front);
  const std::string dir = ::testing::TempDir();
  const render::RenderPart smooth{positions, normals, indices}, flat{positions, {}, indices};
  ASSERT_TRUE(render::RenderPng(dir + "smooth.png", camera, std::span(&smooth, 1)).ok());
  ASSERT_TRUE(render::RenderPng(dir + "flat.png", camera, std::span(&flat, 1)).ok());
  const Pixels sp = ReadPng(dir + "smooth.png"), fp = ReadPng(dir + "flat.png");
  // Along the middle row, inside the square (away from its antialiased edges).
  const int y = sp.height / 2;
  const int x0 = static_cast<int>(camera.Project({-0.9f, 0, 0}).x);
  const int x1 = static_cast<int>(camera.Project({0.9f, 0, 0}).x);
  std::set<uint32_t> smooth_shades, flat_shades;
  for (int x = x0; x <= x1; ++x) {
    smooth_shades.insert(sp.at(x, y));
    flat_shades.insert(fp.at(x, y));
  }
  EXPECT_EQ(flat_shades.size(), 1u);
  EXPECT_GE(smooth_shades.size(), 10u) << "normals turning across the square shade it smoothly";
  // The light comes from a touch left of the viewer: the left-turned side is brighter.
  EXPECT_GT(sp.at(x0, y) & 0xFF0000u, sp.at(x1, y) & 0xFF0000u);
}

TEST(RendererTest, BadInputAndUnwritablePathsAreErrors) {
  const TestMesh box = Box({0, 0, 0}, {1, 1, 1});
  const render::Camera camera = CameraFor(box, 64, 64);
  std::vector<uint32_t> indices = box.indices;
  indices[5] = 8;
  Status s = render::RenderPng(::testing::TempDir() + "bad.png", camera, box.positions, indices);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "indices[5] = 8 is not below vertex_count 8");

  std::vector<float> positions = box.positions;
  positions[7] = std::nanf("");
  s = render::RenderPng(::testing::TempDir() + "bad.png", camera, positions, box.indices);
  EXPECT_EQ(s.message(), "positions[vertex 2] is not finite");

  s = render::RenderPng("/nonexistent-dir/frame.png", camera, box.positions, box.indices);
  EXPECT_EQ(s.code(), StatusCode::kInternal);
  EXPECT_NE(s.message().find("/nonexistent-dir/frame.png"), std::string::npos) << s.message();

  EXPECT_EQ(render::BoundsOf({}).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace skinserve::testing
