// A real character through the renderer: CesiumMan's whole character (CharacterMeshes)
// skinned locally (float64 reference, normals included: smooth shading) over its whole
// clip, every frame drawn from the one camera that frames the clip. Each image must show
// the figure standing, inside the frame: a camera that loses limbs mid-clip fails here.
#include <gtest/gtest.h>

#include <algorithm>
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

}  // namespace
}  // namespace skinserve::testing
