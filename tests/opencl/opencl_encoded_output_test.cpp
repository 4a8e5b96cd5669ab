// Encoded output written by the OpenCL kernels (SkinFrame::encoded, opencl_encode.h), on
// every OpenCL path (copy, zero copy, staged through pinned memory, coalesced): each
// encoding's bytes decoded with core/encoding and compared with the float64 reference
// within float32's tolerance plus the encoding's stated bound, positions, normals and
// tangents, on a vertex count that leaves a partial work-group; a box with an empty axis
// (snorm16's zero-extent case); and a float16 overflow refused naming the vertex.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "opencl_test_support.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

class OpenClEncodedOutputTest : public ::testing::TestWithParam<std::string> {};

// The float64 reference's box of the skinned positions, per axis.
Bounds ReferenceBox(const ReferenceFrame& reference) {
  Bounds box{{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
  for (std::size_t i = 0; i < reference.positions.size(); ++i) {
    box.min[i % 3] = std::min(box.min[i % 3], static_cast<float>(reference.positions[i]));
    box.max[i % 3] = std::max(box.max[i % 3], static_cast<float>(reference.positions[i]));
  }
  return box;
}

TEST_P(OpenClEncodedOutputTest, EveryEncodingMatchesTheReference) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 20011, kJoints = 77;  // not a multiple of 256
  auto mesh = SyntheticMesh(kVertices, 4, kJoints, true, 5, /*tangents=*/true);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (VertexEncoding encoding : {VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    ASSERT_TRUE(backend.info().WritesEncoding(encoding));
    for (uint64_t frame = 0; frame < 3; ++frame) {
      SCOPED_TRACE(::testing::Message() << VertexEncodingName(encoding) << " frame " << frame);
      const auto palette = MakeSyntheticPalette(kJoints, 5, frame);
      std::vector<std::byte> positions(EncodedBytes(encoding, kVertices), std::byte{0x55});
      std::vector<std::byte> normals(positions.size(), std::byte{0x55});
      std::vector<std::byte> tangents(EncodedTangentBytes(encoding, kVertices), std::byte{0x55});
      Bounds box{{NAN, NAN, NAN}, {NAN, NAN, NAN}};
      SkinFrame skin{.palette = palette};
      skin.encoded = {.encoding = encoding,
                      .positions = positions,
                      .normals = normals,
                      .tangents = tangents,
                      .bounds = &box};
      ASSERT_TRUE(skin.Validate(*mesh).ok());
      const Status s = backend.Skin(**prepared, skin);
      ASSERT_TRUE(s.ok()) << s.ToString();
      if (encoding != VertexEncoding::kSnorm16) box = Bounds{};
      std::vector<float> p(3 * kVertices), n(3 * kVertices), t(4 * kVertices);
      ASSERT_TRUE(DecodePositions(encoding, positions, box, p).ok());
      ASSERT_TRUE(DecodeNormals(encoding, normals, n).ok());
      ASSERT_TRUE(DecodeTangents(encoding, tangents, t).ok());
      const EncodedDeviation d = CompareEncodedWithReference(*mesh, palette, encoding, box, p, n);
      EXPECT_TRUE(d.within_tolerance())
          << "position ratio " << d.worst_position_ratio << ", normal ratio "
          << d.worst_normal_ratio << " at vertex " << d.worst_vertex;
      const ReferenceFrame reference = ReferenceSkin(*mesh, palette);
      if (encoding == VertexEncoding::kSnorm16) {  // the box of the skinned positions
        const Bounds expected = ReferenceBox(reference);
        for (int a = 0; a < 3; ++a) {
          EXPECT_NEAR(box.min[a], expected.min[a], 1e-4 * (1 + std::fabs(expected.min[a])));
          EXPECT_NEAR(box.max[a], expected.max[a], 1e-4 * (1 + std::fabs(expected.max[a])));
        }
      }
      EXPECT_EQ(TangentValuesOutsideBound(encoding, t, reference.tangents), 0u)
          << "tangent values outside float32 + the encoding's bound";
    }
  }
}

// Issue 29's pairing: a quantized rest stream in, snorm16 (and float16) out, both on the
// device, tangents included; the decoded frame against the float64 reference of the
// dequantized input.
TEST_P(OpenClEncodedOutputTest, AQuantizedMeshEncodesOnTheDeviceToo) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 3001, kJoints = 77;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = kVertices,
                                               .influences = 4,
                                               .joint_count = kJoints,
                                               .normals = true,
                                               .tangents = true,
                                               .seed = 31});
  auto mesh = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const auto palette = MakeSyntheticPalette(kJoints, 31, 4);
  for (VertexEncoding encoding : {VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    SCOPED_TRACE(VertexEncodingName(encoding));
    std::vector<std::byte> positions(EncodedBytes(encoding, kVertices));
    std::vector<std::byte> normals(positions.size());
    std::vector<std::byte> tangents(EncodedTangentBytes(encoding, kVertices));
    Bounds box;
    SkinFrame skin{.palette = palette};
    skin.encoded = {.encoding = encoding,
                    .positions = positions,
                    .normals = normals,
                    .tangents = tangents,
                    .bounds = &box};
    const Status s = backend.Skin(**prepared, skin);
    ASSERT_TRUE(s.ok()) << s.ToString();
    if (encoding != VertexEncoding::kSnorm16) box = Bounds{};
    std::vector<float> p(3 * kVertices), n(3 * kVertices), t(4 * kVertices);
    ASSERT_TRUE(DecodePositions(encoding, positions, box, p).ok());
    ASSERT_TRUE(DecodeNormals(encoding, normals, n).ok());
    ASSERT_TRUE(DecodeTangents(encoding, tangents, t).ok());
    const EncodedDeviation d = CompareEncodedWithReference(**mesh, palette, encoding, box, p, n);
    EXPECT_TRUE(d.within_tolerance())
        << "position ratio " << d.worst_position_ratio << ", normal ratio " << d.worst_normal_ratio
        << " at vertex " << d.worst_vertex;
    EXPECT_EQ(TangentValuesOutsideBound(encoding, t, ReferenceSkin(**mesh, palette).tangents), 0u)
        << "tangent values outside float32 + the encoding's bound";
  }
}

// Every joint maps x to 0: the box's x axis is empty, and snorm16 writes q = 0 there (the
// host encoder's rule); y and z as usual.
TEST_P(OpenClEncodedOutputTest, AnEmptyAxisOfTheBoxEncodesAsZero) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 1000, kJoints = 77;
  auto mesh = SyntheticMesh(kVertices, 2, kJoints, false, 8);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  auto palette = MakeSyntheticPalette(kJoints, 8, 1);
  for (uint32_t j = 0; j < kJoints; ++j) {
    for (int c = 0; c < 4; ++c) palette[12 * j + c] = 0.0f;  // row 0: x = 0
  }
  std::vector<std::byte> positions(EncodedBytes(VertexEncoding::kSnorm16, kVertices));
  Bounds box;
  SkinFrame skin{.palette = palette};
  skin.encoded = {.encoding = VertexEncoding::kSnorm16, .positions = positions, .bounds = &box};
  const Status s = backend.Skin(**prepared, skin);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(box.min[0], 0.0f);
  EXPECT_EQ(box.max[0], 0.0f);
  std::size_t nonzero_x = 0;
  for (uint32_t v = 0; v < kVertices; ++v) {
    int16_t q;
    std::memcpy(&q, positions.data() + 6 * v, 2);
    nonzero_x += q != 0;
  }
  EXPECT_EQ(nonzero_x, 0u);
  std::vector<float> p(3 * kVertices);
  ASSERT_TRUE(DecodePositions(VertexEncoding::kSnorm16, positions, box, p).ok());
  const EncodedDeviation d =
      CompareEncodedWithReference(*mesh, palette, VertexEncoding::kSnorm16, box, p, {});
  EXPECT_TRUE(d.within_tolerance()) << d.worst_position_ratio << " at vertex " << d.worst_vertex;
}

// float16 holds at most 65504: a frame beyond it fails naming the first vertex and axis
// beyond, as the host encoder does (the device only raises a flag).
TEST_P(OpenClEncodedOutputTest, Float16OverflowIsRefusedNamingTheVertex) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 700, kJoints = 77;
  auto mesh = SyntheticMesh(kVertices, 2, kJoints, true, 9);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  auto palette = MakeSyntheticPalette(kJoints, 9, 2);
  for (uint32_t j = 0; j < kJoints; ++j) palette[12 * j + 7] = 1e6f;  // y + 1e6
  std::vector<std::byte> positions(EncodedBytes(VertexEncoding::kFloat16, kVertices));
  std::vector<std::byte> normals(positions.size());
  SkinFrame skin{.palette = palette};
  skin.encoded = {.encoding = VertexEncoding::kFloat16, .positions = positions, .normals = normals};
  const Status s = backend.Skin(**prepared, skin);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("positions[vertex 0][y]"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("beyond float16's range"), std::string::npos) << s.ToString();
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClEncodedOutputTest, ::testing::ValuesIn(OpenClBackendIds()),
                         BackendTestName);

}  // namespace
}  // namespace skinserve::testing
