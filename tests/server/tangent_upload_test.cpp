// Tangents (glTF TANGENT) on upload through a real server over loopback gRPC: a mesh with
// tangents and morph tangent deltas, sent in chunks like every array, is stored with the
// content id and size the model computes (tangents count in both) and reports
// has_tangents; backends say which skin tangents; bad tangents are refused naming the
// field, the vertex and the limit; a skin request for a mesh with tangents that does not
// ask for them answers positions and normals matching the float64 reference (asking for
// them: tangent_response_test.cpp).
#include <gtest/gtest.h>

#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

MeshArrays TangentArrays() {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2003,
                                         .influences = 4,
                                         .joint_count = 30,
                                         .normals = true,
                                         .tangents = true,
                                         .seed = 5});
  AddSyntheticMorphTargets({.targets = 6, .fraction = 0.2, .seed = 5}, &arrays);
  return arrays;
}

TEST(TangentUploadTest, StoresTangentsAndTheirMorphDeltasAndBackendsSayWhoSkinsThem) {
  TestServer t;
  const MeshArrays arrays = TangentArrays();
  ASSERT_FALSE(arrays.morph_tangent_deltas.empty());
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  EXPECT_TRUE(info->has_tangents());
  EXPECT_EQ(info->mesh_id(), mesh->id());
  EXPECT_EQ(info->bytes(), mesh->byte_size());
  MeshArrays without = arrays;
  without.tangents.clear();
  without.morph_tangent_deltas.clear();
  EXPECT_NE(info->mesh_id(), Mesh::Create(without).value()->id());
  auto got = t.client->GetMesh(info->mesh_id());
  ASSERT_TRUE(got.ok()) << got.status().ToString();
  EXPECT_TRUE(got->has_tangents());
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  for (const auto& b : list->backends()) {  // every backend that runs here, OpenCL included
    EXPECT_EQ(b.tangents(), b.available()) << b.id();
  }
}

TEST(TangentUploadTest, BadTangentsAreRefusedNamingTheFieldAndTheLimit) {
  TestServer t;
  MeshArrays arrays = TangentArrays();
  arrays.tangents[4 * 17 + 3] = 0.0f;
  auto info = t.client->Upload(arrays);
  ASSERT_FALSE(info.ok());
  EXPECT_EQ(info.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(info.status().message().find("tangents[vertex 17].w = 0; it must be exactly +1 or -1"),
            std::string::npos)
      << info.status().ToString();
  arrays = TangentArrays();
  arrays.normals.clear();
  arrays.morph_normal_deltas.clear();
  info = t.client->Upload(arrays);
  ASSERT_FALSE(info.ok());
  EXPECT_EQ(info.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(info.status().message().find("tangents need normals"), std::string::npos)
      << info.status().ToString();
}

TEST(TangentUploadTest, AMeshWithTangentsSkinsAsBeforeOnTheWire) {
  TestServer t;
  const MeshArrays arrays = TangentArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  const auto palette = MakeSyntheticPalette(30, 5, 1);
  const std::vector<MorphWeight> weights = MakeMorphWeights(6, 3, 5, 1);
  client::SkinOptions options;
  options.backend = "simd";
  options.want_normals = true;
  options.morph_weights = weights;
  client::FrameResult result;
  const Status s = t.client->Skin(info->mesh_id(), palette, 1, options, &result);
  ASSERT_TRUE(s.ok()) << s.ToString();
  const Deviation d = CompareWithReference(*mesh, palette, result.positions, result.normals,
                                           SkinningMethod::kLinear, weights);
  EXPECT_TRUE(d.within_tolerance())
      << "position error " << d.max_position_error << " (tolerance " << d.position_tolerance
      << "), normal error " << d.max_normal_error << " (tolerance " << d.normal_tolerance << ")";
}

}  // namespace
}  // namespace skinserve::testing
