// Imported glTF tangents, end to end: the character mesh the CLI's `upload`/`animate`
// send (CharacterMeshes, SkinClient::Upload) reaches a real server over loopback with its
// tangents and morph tangent deltas, and the server's engine skins them where a float64
// morph-then-skin of the values the test wrote (tangent_scene.h) puts them. No response
// carries tangents yet, so the frame is skinned through the server's Engine directly.
// skinserve-load's glTF workload carries them too, and leaves them behind for a quantized
// rest stream (which has none).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "tangent_scene.h"
#include "test_server.h"
#include "workload.h"

namespace skinserve::testing {
namespace {

// Joint j: rotation by `angle` about `axis`, times `scale`, then `t`; 3x4 row-major.
std::vector<double> Joint(std::array<double, 3> axis, double angle, double scale,
                          std::array<double, 3> t) {
  const double n = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  const double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n;
  const double c = std::cos(angle), s = std::sin(angle), k = 1 - c;
  const double r[9] = {c + x * x * k,     x * y * k - z * s, x * z * k + y * s,
                       y * x * k + z * s, c + y * y * k,     y * z * k - x * s,
                       z * x * k - y * s, z * y * k + x * s, c + z * z * k};
  std::vector<double> m;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m.push_back(scale * r[3 * row + col]);
    m.push_back(t[static_cast<std::size_t>(row)]);
  }
  return m;
}

// Linear blend skinning of the scene's tangents in float64: the rest tangent (renormalised,
// as the importer must) plus the weighted morph deltas, through the blended upper 3x3,
// renormalised; w the rest tangent's sign. Parts one after another, as CharacterMeshes
// concatenates them.
std::vector<double> ReferenceTangents(const TangentScene& scene, const std::vector<float>& palette,
                                      const std::vector<double>& morph_weights) {
  std::vector<double> out;
  for (std::size_t i = 0; i < scene.primitives.size(); ++i) {
    const TangentScenePrimitive& p = scene.primitives[i];
    for (std::size_t v = 0; v < p.vertex_count; ++v) {
      const double* rest = &p.tangents[4 * v];
      const double length = std::sqrt(rest[0] * rest[0] + rest[1] * rest[1] + rest[2] * rest[2]);
      double t[3];
      for (int c = 0; c < 3; ++c) {
        t[c] = rest[c] / length;
        for (std::size_t k = 0; k < p.target_tangents.size() && i == 0; ++k) {
          t[c] += morph_weights[k] * p.target_tangents[k][3 * v + c];
        }
      }
      double sum = 0, m[9] = {};
      for (int b = 0; b < 4; ++b) sum += p.weights[4 * v + b];
      for (int b = 0; b < 4; ++b) {
        const double w = p.weights[4 * v + b] / sum;
        const float* joint = &palette[12 * static_cast<std::size_t>(p.joints[4 * v + b])];
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) m[3 * r + c] += w * joint[4 * r + c];
        }
      }
      double skinned[3], norm = 0;
      for (int r = 0; r < 3; ++r) {
        skinned[r] = m[3 * r] * t[0] + m[3 * r + 1] * t[1] + m[3 * r + 2] * t[2];
        norm += skinned[r] * skinned[r];
      }
      for (int r = 0; r < 3; ++r) out.push_back(skinned[r] / std::sqrt(norm));
      out.push_back(rest[3] > 0 ? 1.0 : -1.0);
    }
  }
  return out;
}

TEST(GltfTangentsE2eTest, ImportedTangentsReachTheServerAndSkinLikeTheFloat64Reference) {
  const TangentScene scene = MakeTangentScene();
  auto character = LoadGltfBytes(BuildGlb(scene.glb));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);
  const MeshArrays& arrays = meshes->front().arrays;

  TestServer t;
  auto info = t.client->Upload(arrays);  // what `skinserve-cli upload FILE.glb` sends
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_TRUE(info->has_tangents());
  EXPECT_EQ(info->vertex_count(), 8u);

  std::vector<float> palette;
  for (const auto& joint : {Joint({1, 2, 3}, 0.7, 1.3, {0.1, -0.2, 0.3}),
                            Joint({-1, 0.5, 2}, -1.1, 0.8, {0.5, 1.0, -0.4})}) {
    palette.insert(palette.end(), joint.begin(), joint.end());
  }
  const std::vector<double> weights = {0.8, -0.5};
  const std::vector<MorphWeight> morph = {{0, 0.8f}, {1, -0.5f}};
  const std::vector<double> expected = ReferenceTangents(scene, palette, weights);
  for (const std::string backend : {"serial", "simd"}) {
    std::vector<float> positions(3 * 8), normals(3 * 8), tangents(4 * 8);
    SkinRequest request{.mesh_id = info->mesh_id(),
                        .backend = backend,
                        .palette = palette,
                        .positions = positions,
                        .normals = normals,
                        .tangents = tangents,
                        .morph_weights = morph};
    const Status s = t.server->engine().SkinBlocking(request);
    ASSERT_TRUE(s.ok()) << backend << ": " << s.ToString();
    for (std::size_t k = 0; k < expected.size(); ++k) {
      // Float skinning of unit vectors: a few float roundings, well under 1e-5.
      EXPECT_NEAR(tangents[k], expected[k], 1e-5) << backend << " vertex " << k / 4 << " " << k % 4;
    }
  }
}

// Writes `glb` to a file of the test's temporary folder; its path.
std::string WriteFile(const Glb& glb, const std::string& name) {
  const std::string path = ::testing::TempDir() + name;
  const std::vector<uint8_t> bytes = BuildGlb(glb);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  return path;
}

TEST(GltfTangentsE2eTest,
     TheLoadToolsWorkloadCarriesTangentsIntoAQuantizedRestStreamWhenAskedBack) {
  TangentScene scene = MakeTangentScene();
  std::string path = WriteFile(scene.glb, "workload-tangents.glb");
  auto w = load::MakeGltfWorkload(path, -1, true);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto character = LoadGltfFile(path);
  ASSERT_TRUE(character.ok());
  MeshArrays mesh = CharacterMeshes(*character).value().front().arrays;
  EXPECT_EQ(w->arrays->tangents, mesh.tangents);
  EXPECT_EQ(w->arrays->morph_tangent_deltas, mesh.morph_tangent_deltas);
  EXPECT_TRUE(w->mesh->has_tangents());

  // A quantized rest stream holds no morph targets: without targets the character loads so,
  // its tangents in the stream when asked back (--tangents), else left behind.
  scene.glb.json["meshes"][0]["primitives"][0].erase("targets");
  path = WriteFile(scene.glb, "workload-tangents-no-targets.glb");
  w = load::MakeGltfWorkload(path, -1, true);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  ASSERT_EQ(w->arrays->tangents.size(), 32u);
  Status s = load::SetRestEncoding(&*w, RestEncoding::kQuantized16);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_TRUE(w->arrays->tangents.empty());
  EXPECT_FALSE(w->mesh->has_tangents());
  EXPECT_EQ(w->arrays->positions, mesh.positions);

  w = load::MakeGltfWorkload(path, -1, true, true);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  s = load::SetRestEncoding(&*w, RestEncoding::kQuantized16);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(w->arrays->tangents.size(), 32u);
  ASSERT_NE(w->mesh->quantized_rest(), nullptr);
  EXPECT_EQ(w->mesh->quantized_rest()->tangents.size(), 32u);
}

}  // namespace
}  // namespace skinserve::testing
