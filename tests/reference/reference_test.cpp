// The reference itself, against poses worked out by hand.
#include "skinserve/reference/reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace skinserve {
namespace {

// One vertex p = (1, 2, 3), n = (1, 0, 0), weighted 0.25 to a translation by (1, 0, 0)
// and 0.75 to a 90-degree rotation about z: (x, y, z) -> (-y, x, z).
struct HandPose {
  std::shared_ptr<const Mesh> mesh;
  std::vector<float> palette = {1, 0,  0, 1, 0, 1, 0, 0, 0, 0, 1, 0,   // translate x by 1
                                0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0};  // rotate z by 90
  HandPose() {
    MeshArrays a;
    a.vertex_count = 1;
    a.influences = 2;
    a.joint_count = 2;
    a.positions = {1, 2, 3};
    a.normals = {1, 0, 0};
    a.joints = {0, 1};
    a.weights = {0.25f, 0.75f};
    mesh = Mesh::Create(a).value();
  }
};

TEST(ReferenceTest, MatchesAPoseWorkedOutByHand) {
  HandPose pose;
  const ReferenceFrame out = ReferenceSkin(*pose.mesh, pose.palette);
  // 0.25 * (2, 2, 3) + 0.75 * (-2, 1, 3)
  EXPECT_DOUBLE_EQ(out.positions[0], -1.0);
  EXPECT_DOUBLE_EQ(out.positions[1], 1.25);
  EXPECT_DOUBLE_EQ(out.positions[2], 3.0);
  // 0.25 * (1, 0, 0) + 0.75 * (0, 1, 0), renormalised
  const double length = std::sqrt(0.25 * 0.25 + 0.75 * 0.75);
  EXPECT_DOUBLE_EQ(out.normals[0], 0.25 / length);
  EXPECT_DOUBLE_EQ(out.normals[1], 0.75 / length);
  EXPECT_DOUBLE_EQ(out.normals[2], 0.0);
}

TEST(ReferenceTest, ComparisonAcceptsRoundingAndCatchesRealErrors) {
  HandPose pose;
  const double length = std::sqrt(0.625);
  std::vector<float> positions = {-1.0f, 1.25f, 3.0f};
  std::vector<float> normals = {static_cast<float>(0.25 / length),
                                static_cast<float>(0.75 / length), 0.0f};
  EXPECT_TRUE(
      CompareWithReference(*pose.mesh, pose.palette, positions, normals).within_tolerance());

  positions[1] += 1e-3f;
  Deviation d = CompareWithReference(*pose.mesh, pose.palette, positions, normals);
  EXPECT_FALSE(d.within_tolerance());
  EXPECT_NEAR(d.max_position_error, 1e-3, 1e-6);

  positions[1] = 1.25f;
  normals[2] = std::numeric_limits<float>::quiet_NaN();
  d = CompareWithReference(*pose.mesh, pose.palette, positions, normals);
  EXPECT_FALSE(d.within_tolerance());
  EXPECT_TRUE(std::isinf(d.max_normal_error));

  std::vector<float> short_output = {-1.0f, 1.25f};
  EXPECT_FALSE(CompareWithReference(*pose.mesh, pose.palette, short_output, {}).within_tolerance());
}

}  // namespace
}  // namespace skinserve
