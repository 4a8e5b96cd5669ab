// Dual-quaternion skinning: every backend that lists it (every computing backend) against
// the independent float64 reference (ReferenceSkinDualQuaternion, on glm) on random rigid
// palettes, B = 1..8, vertex counts that leave tails, 1, 77 and 300 joints (`simd`
// streams 8-bit joints up to 256, 16-bit above), with and without normals; the twist,
// where it must keep the tube's radius while linear blending collapses it; three joints whose
// quaternions are not in one hemisphere, in every order; and the method lists. (`simd` at every
// SIMD target: simd_targets_test.cpp; the OpenCL kernels' own cases and the staged copy path:
// tests/opencl.) Tolerance: CompareWithReference's (1e-5 relative to the frame's scale, 1e-5 on
// normals).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <tuple>

#include "backend_fixture.h"
#include "reference_cases.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/twist_cylinder.h"

namespace skinserve::testing {
namespace {

std::vector<MeshCase> Cases() {
  std::vector<MeshCase> cases = MeshCases({1, 7, 1001}, {1, 77, 300});
  cases.push_back({LargeCaseVertices(), 4, 77, true, true});
  return cases;
}

class DualQuaternionConformanceTest : public ::testing::TestWithParam<BackendCase> {};

TEST_P(DualQuaternionConformanceTest, MatchesTheFloat64Reference) {
  const auto& [id, c] = GetParam();
  Backend& backend = BackendById(id);
  SKIP_IF_UNAVAILABLE(backend);
  auto mesh = CaseMesh(c);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (uint64_t frame = 0; frame < 2; ++frame) {
    const auto palette = MakeRigidPalette(c.joints, CaseSeed(c), frame);
    ExpectFrameMatchesReference(backend, **prepared, *mesh, palette, c,
                                SkinningMethod::kDualQuaternion, "frame " + std::to_string(frame));
  }
}

INSTANTIATE_TEST_SUITE_P(
    DualQuaternionBackends, DualQuaternionConformanceTest,
    ::testing::Combine(::testing::ValuesIn(BackendIdsWithMethod(SkinningMethod::kDualQuaternion)),
                       ::testing::ValuesIn(Cases())),
    CaseName);

// The reference itself, on cases worked by hand: a joint's own rigid motion comes out
// exactly, and two joints at +-90 degrees about one axis blend to the half-way rotation
// whichever quaternion sign the conversion picks.
TEST(DualQuaternionReferenceTest, OneJointIsItsRigidMotion) {
  MeshArrays arrays{.vertex_count = 1,
                    .influences = 1,
                    .joint_count = 1,
                    .positions = {1, 2, 3},
                    .normals = {0, 0, 1},
                    .joints = {0},
                    .weights = {1}};
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok());
  // 90 degrees about +z, then move by (10, 20, 30): (1, 2, 3) -> (-2, 1, 3) + t.
  const std::vector<float> palette = {0, -1, 0, 10, 1, 0, 0, 20, 0, 0, 1, 30};
  const ReferenceFrame ref = ReferenceSkinDualQuaternion(**mesh, palette);
  EXPECT_NEAR(ref.positions[0], 8, 1e-12);
  EXPECT_NEAR(ref.positions[1], 21, 1e-12);
  EXPECT_NEAR(ref.positions[2], 33, 1e-12);
  EXPECT_NEAR(ref.normals[2], 1, 1e-12);
}

TEST(DualQuaternionReferenceTest, BlendsAcrossHemispheresTheShortWay) {
  // Joint 0: 170 degrees about +y; joint 1: -170 degrees (190). Their quaternions have a
  // negative dot product; blended half and half the short way is 180 degrees, not 0.
  const double a = 170 * std::numbers::pi / 180;
  const float c = static_cast<float>(std::cos(a)), s = static_cast<float>(std::sin(a));
  const std::vector<float> palette = {c, 0, s,  0, 0, 1, 0, 0, -s, 0, c, 0,
                                      c, 0, -s, 0, 0, 1, 0, 0, s,  0, c, 0};
  MeshArrays arrays{.vertex_count = 1,
                    .influences = 2,
                    .joint_count = 2,
                    .positions = {0, 0, 1},
                    .normals = {},
                    .joints = {0, 1},
                    .weights = {0.5f, 0.5f}};
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok());
  const ReferenceFrame ref = ReferenceSkinDualQuaternion(**mesh, palette);
  EXPECT_NEAR(ref.positions[0], 0, 1e-6);
  EXPECT_NEAR(ref.positions[2], -1, 1e-6);
}

// The radius of the middle ring (weights 1/2, 1/2) around the cylinder's axis: min, max.
std::pair<double, double> MiddleRingRadius(const TwistCylinder& cylinder,
                                           std::span<const float> positions) {
  const uint32_t ring = cylinder.rings / 2;
  double lo = 1e30, hi = 0;
  for (uint32_t k = 0; k < cylinder.segments; ++k) {
    const float* p = &positions[3 * (ring * cylinder.segments + k)];
    const double r = std::hypot(double{p[0]}, double{p[2]});
    lo = std::min(lo, r), hi = std::max(hi, r);
  }
  return {lo, hi};
}

class TwistTest : public ::testing::TestWithParam<std::string> {};

TEST_P(TwistTest, DualQuaternionsKeepTheRadiusWhereLinearCollapses) {
  Backend& backend = BackendById(GetParam());
  SKIP_IF_UNAVAILABLE(backend);
  const TwistCylinder cylinder = MakeTwistCylinder();
  auto mesh = Mesh::Create(cylinder.mesh);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (int degrees = 0; degrees <= 180; degrees += 15) {
    const auto palette = MakeTwistPalette(degrees);
    const Output dqs =
        SkinOnce(backend, **prepared, palette, true, SkinningMethod::kDualQuaternion);
    const Output linear = SkinOnce(backend, **prepared, palette, false, SkinningMethod::kLinear);
    const auto [dqs_min, dqs_max] = MiddleRingRadius(cylinder, dqs.positions);
    const auto [linear_min, linear_max] = MiddleRingRadius(cylinder, linear.positions);
    // Dual quaternions: a rotation by half the twist, the radius unchanged.
    EXPECT_NEAR(dqs_min, cylinder.radius, 1e-5) << GetParam() << " at " << degrees << " degrees";
    EXPECT_NEAR(dqs_max, cylinder.radius, 1e-5) << GetParam() << " at " << degrees << " degrees";
    // Linear: the average of two rotations shrinks the ring to radius * cos(twist / 2).
    const double collapsed = cylinder.radius * std::cos(degrees * std::numbers::pi / 360);
    EXPECT_NEAR(linear_min, collapsed, 1e-5) << GetParam() << " at " << degrees << " degrees";
    EXPECT_NEAR(linear_max, collapsed, 1e-5) << GetParam() << " at " << degrees << " degrees";
    // And both agree with their float64 references everywhere, not only on that ring.
    EXPECT_TRUE(CompareWithReference(**mesh, palette, dqs.positions, dqs.normals,
                                     SkinningMethod::kDualQuaternion)
                    .within_tolerance())
        << GetParam() << " at " << degrees << " degrees";
  }
  // At 180 degrees linear blending has collapsed the middle ring onto the axis.
  const Output linear =
      SkinOnce(backend, **prepared, MakeTwistPalette(180), false, SkinningMethod::kLinear);
  EXPECT_LT(MiddleRingRadius(cylinder, linear.positions).second, 1e-6);
}

INSTANTIATE_TEST_SUITE_P(DualQuaternionBackends, TwistTest,
                         ::testing::ValuesIn(BackendIdsWithMethod(SkinningMethod::kDualQuaternion)),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// Three joints at 0, 120 and 240 degrees about z. Their quaternions (Shepperd's
// conversion: (0 0 0 1), (0 0 .866 .5), (0 0 .866 -.5)) are not in one hemisphere: q0.q1 =
// 0.5, q1.q2 = 0.5, but q0.q2 = -0.5. So each influence's sign depends on which joint is
// the vertex's first: with joints (1, 0, 2) and weights (.5, .3, .2) the blend against
// joint 1 is (0 0 .61 .45), a rotation by 107 degrees; against joint 0 (wrong) it would be
// (0 0 .26 .65), 44 degrees.
// Every ordering of the joints, 4 vertices (per-vertex signs on `simd`: fewer dot products
// than the table's 9) and 6 and 600 (its per-frame hemisphere table, past one 256-vertex
// chunk), each checked against the float64 reference, which takes the first's hemisphere.
class HemisphereTest : public ::testing::TestWithParam<std::string> {};

TEST_P(HemisphereTest, EachInfluenceTakesTheFirstInfluencesHemisphere) {
  Backend& backend = BackendById(GetParam());
  SKIP_IF_UNAVAILABLE(backend);
  const double third = 2 * std::numbers::pi / 3;
  std::vector<float> palette;
  const float translations[3][3] = {{1, 2, 3}, {-2, 0, 1}, {0, 3, -1}};
  for (int j = 0; j < 3; ++j) {
    const float c = static_cast<float>(std::cos(j * third));
    const float s = static_cast<float>(std::sin(j * third));
    const std::vector<float> m = {c, -s, 0, translations[j][0], s, c, 0, translations[j][1],
                                  0, 0,  1, translations[j][2]};
    palette.insert(palette.end(), m.begin(), m.end());
  }
  const uint32_t orders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (uint32_t vertices : {4u, 6u, 600u}) {
    MeshArrays arrays{.vertex_count = vertices, .influences = 3, .joint_count = 3};
    for (uint32_t v = 0; v < vertices; ++v) {
      const float f = static_cast<float>(v);
      arrays.positions.insert(arrays.positions.end(), {1 + 0.01f * f, -0.5f, 0.25f * (v % 7)});
      const float n[3] = {0.6f, 0, 0.8f};
      arrays.normals.insert(arrays.normals.end(), n, n + 3);
      arrays.joints.insert(arrays.joints.end(), orders[v % 6], orders[v % 6] + 3);
      arrays.weights.insert(arrays.weights.end(), {0.5f, 0.3f, 0.2f});
    }
    auto mesh = Mesh::Create(arrays);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    auto prepared = backend.Prepare(*mesh);
    ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
    const Output out =
        SkinOnce(backend, **prepared, palette, true, SkinningMethod::kDualQuaternion);
    const Deviation d = CompareWithReference(**mesh, palette, out.positions, out.normals,
                                             SkinningMethod::kDualQuaternion);
    EXPECT_TRUE(d.within_tolerance())
        << GetParam() << " V=" << vertices << ": position error " << d.max_position_error
        << " (tolerance " << d.position_tolerance << "), normal error " << d.max_normal_error
        << ", worst vertex " << d.worst_vertex;
  }
}

INSTANTIATE_TEST_SUITE_P(DualQuaternionBackends, HemisphereTest,
                         ::testing::ValuesIn(BackendIdsWithMethod(SkinningMethod::kDualQuaternion)),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                           std::string name = param.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(DualQuaternionMethodsTest, EveryComputingBackendListsIt) {
  // Every backend that runs here but passthrough (the SSE ones off x86 and the OpenCL
  // ones without a platform are listed unavailable, with their reason).
  int listing = 0;
  for (const auto& backend : AllBackends()) {
    const BackendInfo& info = backend->info();
    EXPECT_TRUE(info.Supports(SkinningMethod::kLinear)) << info.id;
    if (!info.available) continue;
    EXPECT_EQ(info.Supports(SkinningMethod::kDualQuaternion), info.id != "passthrough") << info.id;
    listing += info.Supports(SkinningMethod::kDualQuaternion) ? 1 : 0;
  }
  // serial, openmp, simd and simd-openmp run everywhere.
  EXPECT_GE(listing, 4);
  for (const char* id : {"serial", "openmp", "simd", "simd-openmp"}) {
    EXPECT_TRUE(BackendById(id).info().Supports(SkinningMethod::kDualQuaternion)) << id;
  }
}

TEST(DualQuaternionMethodsTest, APaletteThatIsNotRigidIsRefusedBeforeSkinning) {
  auto mesh = Mesh::Create(MakeSyntheticMesh(
      {.vertex_count = 10, .influences = 2, .joint_count = 3, .normals = false, .seed = 5}));
  ASSERT_TRUE(mesh.ok());
  std::vector<float> positions(30);
  std::vector<float> palette = MakeRigidPalette(3, 5, 0);
  const SkinFrame rigid{
      .palette = palette, .positions = positions, .method = SkinningMethod::kDualQuaternion};
  EXPECT_TRUE(rigid.Validate(**mesh).ok());
  palette = MakeSyntheticPalette(3, 5, 0);  // scaled by 0.9..1.1: fine for linear only
  const SkinFrame scaled{
      .palette = palette, .positions = positions, .method = SkinningMethod::kDualQuaternion};
  const Status s = scaled.Validate(**mesh);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("palette[joint 0] is not rigid"), std::string::npos) << s.message();
  const SkinFrame linear{
      .palette = palette, .positions = positions, .method = SkinningMethod::kLinear};
  EXPECT_TRUE(linear.Validate(**mesh).ok());
}

}  // namespace
}  // namespace skinserve::testing
