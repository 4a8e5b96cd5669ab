// CompareEncodedWithReference: a frame skinned in float64, rounded to float32, sent through
// each encoding and decoded passes; the same frame pushed past the stated bound fails.
#include "skinserve/reference/encoded_reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

struct Frame {
  std::shared_ptr<const Mesh> mesh;
  std::vector<float> palette;
  std::vector<float> positions, normals;  // the reference rounded to float32
  Frame() {
    mesh = Mesh::Create(MakeSyntheticMesh(
                            {.vertex_count = 3001, .influences = 3, .normals = true, .seed = 4}))
               .value();
    palette = MakeSyntheticPalette(mesh->joint_count(), 4, 9);
    const ReferenceFrame ref = ReferenceSkin(*mesh, palette);
    positions.assign(ref.positions.begin(), ref.positions.end());
    normals.assign(ref.normals.begin(), ref.normals.end());
  }
};

std::vector<float> RoundTrip(VertexEncoding e, const std::vector<float>& values, const Bounds& b,
                             bool normals) {
  std::vector<std::byte> bytes(values.size() * EncodedBytesPerValue(e));
  std::vector<float> out(values.size());
  EXPECT_TRUE(
      (normals ? EncodeNormals(e, values, bytes) : EncodePositions(e, values, b, bytes)).ok());
  EXPECT_TRUE((normals ? DecodeNormals(e, bytes, out) : DecodePositions(e, bytes, b, out)).ok());
  return out;
}

TEST(EncodedReferenceTest, EveryEncodingPassesAndAWrongValueFails) {
  const Frame f;
  const Bounds box = ComputeBounds(f.positions).value();
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    std::vector<float> p = RoundTrip(e, f.positions, box, false);
    std::vector<float> n = RoundTrip(e, f.normals, box, true);
    EncodedDeviation d = CompareEncodedWithReference(*f.mesh, f.palette, e, box, p, n);
    EXPECT_TRUE(d.within_tolerance())
        << VertexEncodingName(e) << " " << d.worst_position_ratio << " " << d.worst_normal_ratio;
    if (e != VertexEncoding::kFloat32) {
      EXPECT_GT(d.worst_position_ratio, 0.1);  // not vacuous
    }
    // Twice the stated bound on one coordinate fails.
    const double bound = PositionEncodingError(e, box, 1, std::fabs(f.positions[301])) + 1e-3;
    p[301] = static_cast<float>(f.positions[301] + 2 * bound);
    d = CompareEncodedWithReference(*f.mesh, f.palette, e, box, p, n);
    EXPECT_FALSE(d.within_tolerance()) << VertexEncodingName(e);
    EXPECT_EQ(d.worst_vertex, 100u);
    p[301] = f.positions[301];
    n[5] = std::nanf("");
    EXPECT_FALSE(CompareEncodedWithReference(*f.mesh, f.palette, e, box, p, n).within_tolerance());
  }
  // A short array is a mismatch, not a pass.
  std::vector<float> short_positions(f.positions.begin(), f.positions.end() - 3);
  EXPECT_FALSE(CompareEncodedWithReference(*f.mesh, f.palette, VertexEncoding::kFloat32, box,
                                           short_positions, {})
                   .within_tolerance());
}

}  // namespace
}  // namespace skinserve
