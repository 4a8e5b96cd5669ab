// The sampler's slerp (a polynomial, no acos or sin) against the true slerp in double,
// keys from 0 to 180 degrees of rotation apart.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "quaternion.h"

namespace skinserve::testing {
namespace {

// Keys `theta` apart (quaternion angle: the rotation turns 2 theta) about an oblique axis.
double WorstError(double max_theta) {
  double worst = 0;
  const double axis[3] = {0.48, -0.6, 0.64};
  for (int i = 0; i <= 500; ++i) {
    const double theta = max_theta * i / 500;
    const float a[4] = {0, 0, 0, 1};
    const float b[4] = {static_cast<float>(axis[0] * std::sin(theta)),
                        static_cast<float>(axis[1] * std::sin(theta)),
                        static_cast<float>(axis[2] * std::sin(theta)),
                        static_cast<float>(std::cos(theta))};
    for (int k = 0; k <= 20; ++k) {
      const double u = k / 20.0;
      float out[4];
      animation::detail::Slerp(a, b, static_cast<float>(u), out);
      const double s =
          std::sqrt(double{out[0]} * out[0] + double{out[1]} * out[1] + double{out[2]} * out[2]);
      const double along = (out[0] * axis[0] + out[1] * axis[1] + out[2] * axis[2]);
      const double off_axis = std::sqrt(std::max(0.0, s * s - along * along));
      const double got = std::atan2(along, double{out[3]});
      worst = std::max(worst, 2 * std::hypot(got - u * theta, off_axis));
    }
  }
  return worst;
}

TEST(Slerp, MatchesTrueSlerpWithinStatedError) {
  EXPECT_LE(WorstError(1.0), 5e-7) << "keys up to 2 rad of rotation apart";
  EXPECT_LE(WorstError(std::numbers::pi / 2 - 1e-4), 2e-5) << "keys up to 180 degrees apart";
}

// q and -q are one rotation: the blend takes the short way round.
TEST(Slerp, TakesTheShortestPath) {
  const float a[4] = {0, 0, 0, 1};
  const float b[4] = {0, 0, -0.38268343f, -0.92387953f};  // -(45 degrees about z)
  float out[4];
  animation::detail::Slerp(a, b, 0.5f, out);
  EXPECT_NEAR(std::fabs(out[2]), std::sin(std::numbers::pi / 16), 1e-6);  // 22.5 degrees
}

}  // namespace
}  // namespace skinserve::testing
