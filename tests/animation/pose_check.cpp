#include "pose_check.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace skinserve::testing {
namespace {

// Where the palette entry's joint sits in the bind pose: the inverse bind's inverse,
// applied to the origin (the point the entry moves onto the joint).
std::array<double, 3> BindPosition(const Mat4& ibm) {  // column-major
  auto a = [&](int r, int c) { return ibm[static_cast<std::size_t>(4 * c + r)]; };
  const double det = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
                     a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
                     a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
  double inv[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const int r1 = (c + 1) % 3, r2 = (c + 2) % 3, c1 = (r + 1) % 3, c2 = (r + 2) % 3;
      inv[r][c] = (a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1)) / det;
    }
  }
  std::array<double, 3> b{};
  for (int r = 0; r < 3; ++r)
    b[static_cast<std::size_t>(r)] =
        -(inv[r][0] * a(0, 3) + inv[r][1] * a(1, 3) + inv[r][2] * a(2, 3));
  return b;
}

}  // namespace

void ExpectRotationNear(const float* m, const double* ref, const PoseBound& bound,
                        const std::string& what, Worst& worst) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double e = std::fabs(m[4 * r + c] - ref[4 * r + c]);
      worst.rotation = std::max(worst.rotation, e);
      EXPECT_LE(e, bound.rotation) << what << " row " << r << " col " << c;
    }
  }
}

double ExpectPointNear(const float* m, const double* ref, const double p[3], const PoseBound& bound,
                       const std::string& what) {
  double d2 = 0, r2 = 0;
  for (int r = 0; r < 3; ++r) {
    const double want =
        ref[4 * r] * p[0] + ref[4 * r + 1] * p[1] + ref[4 * r + 2] * p[2] + ref[4 * r + 3];
    const double got = m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3];
    d2 += (got - want) * (got - want);
    r2 += want * want;
  }
  const double limit = bound.absolute + bound.relative * std::sqrt(r2);
  EXPECT_LE(std::sqrt(d2), limit) << what << " off by " << std::sqrt(d2) << " m";
  return std::sqrt(d2) / limit;
}

void ExpectPoseMatches(const PoseCase& c, const RuntimePose& pose, double t, const PoseBound& bound,
                       Worst& worst) {
  const std::vector<double> ref = RefModel(c, t);
  const std::size_t joints = c.skeleton.joint_count();
  const double origin[3] = {0, 0, 0};
  for (std::size_t j = 0; j < joints; ++j) {
    const std::string what = c.label + " t " + std::to_string(t) + " joint " + std::to_string(j);
    worst.position = std::max(worst.position,
                              ExpectPointNear(pose.model[j].m, &ref[12 * j], origin, bound, what));
    ExpectRotationNear(pose.model[j].m, &ref[12 * j], bound, what, worst);
  }
  for (std::size_t p = 0; p < c.skeleton.palette_size(); ++p) {
    const std::string what = c.label + " t " + std::to_string(t) + " palette " + std::to_string(p);
    const std::array<double, 3> bind = BindPosition(c.ref.inverse_bind[p]);
    worst.palette = std::max(
        worst.palette,
        ExpectPointNear(&pose.palette[12 * p], &ref[12 * (joints + p)], bind.data(), bound, what));
    ExpectRotationNear(&pose.palette[12 * p], &ref[12 * (joints + p)], bound, what, worst);
  }
  const std::vector<double> weights = RefWeightsAt(c, t);
  ASSERT_EQ(pose.weights.size(), weights.size()) << c.label;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    worst.weight = std::max(worst.weight, std::fabs(pose.weights[i] - weights[i]));
    EXPECT_NEAR(pose.weights[i], weights[i], 1e-4) << c.label << " t " << t << " weight " << i;
  }
}

}  // namespace skinserve::testing
