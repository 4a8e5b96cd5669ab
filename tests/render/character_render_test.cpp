// A real character through the renderer: CesiumMan's whole character (CharacterMeshes)
// skinned locally (float64 reference, normals included: smooth shading) over its whole
// clip, every frame drawn from the one camera that frames the clip. Each image must show
// the figure standing, inside the frame: a camera that loses limbs mid-clip fails here.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>

#include "png_pixels.h"
#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/reference/reference.h"
#include "skinserve/render/character_camera.h"
#include "skinserve/render/mesh_renderer.h"

namespace skinserve::testing {
namespace {

TEST(CharacterRenderTest, EveryFrameOfTheClipStandsInsideTheClipCamera) {
  const std::string path = std::string(SKINSERVE_GLTF_ASSETS) + "/CesiumMan.glb";
  ASSERT_TRUE(std::filesystem::exists(path))
      << path << " is missing: it is part of the repository (tests/assets/gltf)";
  auto character = LoadGltfFile(path);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);
  const CharacterMesh& whole = meshes->front();
  const AnimationClip* clip = character->FindClip("");
  ASSERT_NE(clip, nullptr);
  const uint64_t frames = 61;  // 2 s at 30 fps
  const std::vector<Pose> poses = render::ClipPoses(*character, *clip, 30.0, frames);
  EXPECT_EQ(poses.size(), 32u);
  auto camera = render::CharacterCamera(*character, *meshes, poses, 240, 320);
  ASSERT_TRUE(camera.ok()) << camera.status().ToString();
  auto mesh = Mesh::Create(whole.arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();

  render::RenderOptions options;
  options.background = {1.0f, 1.0f, 1.0f};
  for (int i = 0; i <= 10; ++i) {
    const double t = clip->duration * i / 10.0;
    auto palette = SkinPalette(*character, SampleClip(*character, *clip, t), whole.skin);
    ASSERT_TRUE(palette.ok()) << palette.status().ToString();
    const ReferenceFrame frame = ReferenceSkin(**mesh, *palette);
    const std::vector<float> positions(frame.positions.begin(), frame.positions.end());
    const std::vector<float> normals(frame.normals.begin(), frame.normals.end());
    ASSERT_FALSE(normals.empty());
    const std::string png = ::testing::TempDir() + "cesium-" + std::to_string(i) + ".png";
    const render::RenderPart part{positions, normals, whole.indices};
    ASSERT_TRUE(
        render::RenderPng(png, *camera, std::span<const render::RenderPart>(&part, 1), options)
            .ok());

    const Pixels p = ReadPng(png);
    ASSERT_EQ(p.width, 240);
    ASSERT_EQ(p.height, 320);
    int min_x = p.width, max_x = -1, min_y = p.height, max_y = -1, covered = 0;
    for (int y = 0; y < p.height; ++y) {
      for (int x = 0; x < p.width; ++x) {
        if (p.at(x, y) == 0xFFFFFFu) continue;
        ++covered;
        min_x = std::min(min_x, x), max_x = std::max(max_x, x);
        min_y = std::min(min_y, y), max_y = std::max(max_y, y);
      }
    }
    SCOPED_TRACE("t = " + std::to_string(t));
    EXPECT_GT(covered, p.width * p.height / 20) << "almost blank";
    EXPECT_GT(min_x, 0);
    EXPECT_GT(min_y, 0);
    EXPECT_LT(max_x, p.width - 1);
    EXPECT_LT(max_y, p.height - 1);
    // Standing: taller than wide, and most of the image's height.
    EXPECT_GT(max_y - min_y, max_x - min_x);
    EXPECT_GT(max_y - min_y, p.height / 2);
  }
}

// Rigid parts through the renderer: two quads on two nodes without a skin, far apart, the
// right one lifted by the clip. The clip's camera must frame both in every frame, and the
// last frame must show the right one risen, the left one still (their nodes' world
// matrices in the palette).
TEST(CharacterRenderTest, RigidPartsAreFramedAndDrawnWhereTheirNodesAre) {
  Character c;
  c.nodes.resize(3);
  c.nodes[0].name = "Root";
  c.nodes[1] = {.name = "Left", .parent = 0, .translation = {-3, 0, 0}};
  c.nodes[2] = {.name = "Right", .parent = 0, .translation = {3, 0, 0}};
  for (int node : {1, 2}) {
    SkinnedPrimitive quad;
    quad.name = node == 1 ? "L/0" : "R/0";
    quad.node = node;
    quad.skin = -1;
    quad.arrays.vertex_count = 4;
    quad.arrays.influences = 1;
    quad.arrays.joint_count = 1;
    quad.arrays.positions = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
    quad.arrays.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    quad.arrays.joints = {0, 0, 0, 0};
    quad.arrays.weights = {1, 1, 1, 1};
    quad.indices = {0, 1, 2, 0, 2, 3};
    c.primitives.push_back(quad);
  }
  AnimationClip lift{.name = "Lift", .duration = 1.0f, .channels = {}};
  lift.channels.push_back({.node = 2,
                           .path = ChannelPath::kTranslation,
                           .interpolation = Interpolation::kLinear,
                           .times = {0, 1},
                           .values = {3, 0, 0, 3, 4, 0}});
  c.clips.push_back(lift);
  auto meshes = CharacterMeshes(c);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);
  const CharacterMesh& whole = meshes->front();
  const std::vector<Pose> poses = render::ClipPoses(c, lift, 10.0, 11);
  auto camera = render::CharacterCamera(c, *meshes, poses, 200, 200);
  ASSERT_TRUE(camera.ok()) << camera.status().ToString();
  auto mesh = Mesh::Create(whole.arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();

  render::RenderOptions options;
  options.background = {1.0f, 1.0f, 1.0f};
  std::vector<std::array<int, 2>> tops;  // per frame: the left and right parts' top rows
  for (double t : {0.0, 1.0}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    auto palette = MeshPalette(c, SampleClip(c, lift, t), whole);
    ASSERT_TRUE(palette.ok()) << palette.status().ToString();
    const ReferenceFrame frame = ReferenceSkin(**mesh, *palette);
    const std::vector<float> positions(frame.positions.begin(), frame.positions.end());
    const std::vector<float> normals(frame.normals.begin(), frame.normals.end());
    const std::string png = ::testing::TempDir() + "rigid-" + std::to_string(t) + ".png";
    const render::RenderPart part{positions, normals, whole.indices};
    ASSERT_TRUE(
        render::RenderPng(png, *camera, std::span<const render::RenderPart>(&part, 1), options)
            .ok());
    const Pixels p = ReadPng(png);
    // Each half holds one quad: its topmost covered row.
    int top[2] = {p.height, p.height};
    int covered[2] = {0, 0};
    for (int y = 0; y < p.height; ++y) {
      for (int x = 0; x < p.width; ++x) {
        if (p.at(x, y) == 0xFFFFFFu) continue;
        const int half = x < p.width / 2 ? 0 : 1;
        ++covered[half];
        top[half] = std::min(top[half], y);
        EXPECT_GT(x, 0);
        EXPECT_LT(x, p.width - 1);
      }
    }
    EXPECT_GT(covered[0], 100) << "the left part is missing";
    EXPECT_GT(covered[1], 100) << "the right part is missing";
    tops.push_back({top[0], top[1]});
  }
  // The camera is fixed: the left part stays where it was, the right one rose (by 4 units,
  // a third of the framed height at least).
  ASSERT_EQ(tops.size(), 2u);
  EXPECT_NEAR(tops[1][0], tops[0][0], 1);
  EXPECT_LT(tops[1][1] + 20, tops[0][1]);
}

}  // namespace
}  // namespace skinserve::testing
