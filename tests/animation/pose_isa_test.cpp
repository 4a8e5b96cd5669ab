// The pose jobs' ISA choice (skinserve/animation/pose_isa.h). The jobs' results under each
// ISA are checked by every other test of this binary: ctest runs it twice, as the CPU
// allows and with SKINSERVE_POSE_ISA=baseline (tests/animation/CMakeLists.txt).
#include "skinserve/animation/pose_isa.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace skinserve::animation {
namespace {

// The baseline run is only a baseline run if the variable is honoured.
TEST(PoseIsa, FollowsTheEnvironment) {
  const char* asked = std::getenv("SKINSERVE_POSE_ISA");
  if (asked == nullptr) {
    EXPECT_EQ(ActivePoseIsa(), BestPoseIsa());
  } else {
    EXPECT_STREQ(PoseIsaName(ActivePoseIsa()), asked);
  }
}

TEST(PoseIsa, SetPoseIsaTakesWhatTheCpuRunsAndRefusesTheRest) {
  const PoseIsa before = ActivePoseIsa();
  ASSERT_TRUE(SetPoseIsa(PoseIsa::kBaseline).ok());
  EXPECT_EQ(ActivePoseIsa(), PoseIsa::kBaseline);
  const Status avx2 = SetPoseIsa(PoseIsa::kAvx2Fma);
  if (BestPoseIsa() == PoseIsa::kAvx2Fma) {
    EXPECT_TRUE(avx2.ok()) << avx2.ToString();
    EXPECT_EQ(ActivePoseIsa(), PoseIsa::kAvx2Fma);
  } else {
    EXPECT_EQ(avx2.code(), StatusCode::kFailedPrecondition);
    EXPECT_NE(avx2.message().find("avx2-fma"), std::string::npos) << avx2.message();
    EXPECT_EQ(ActivePoseIsa(), PoseIsa::kBaseline);
  }
  ASSERT_TRUE(SetPoseIsa(before).ok());
}

}  // namespace
}  // namespace skinserve::animation
