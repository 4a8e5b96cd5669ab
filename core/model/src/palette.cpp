#include "skinserve/model/palette.h"

#include <fmt/format.h>
#include <cmath>
#include <string>

namespace skinserve {

Status ValidatePalette(std::span<const float> palette, uint32_t joint_count) {
  const std::size_t expected = kFloatsPerJoint * joint_count;
  if (palette.size() != expected) {
    return InvalidArgument(
        fmt::format("palette holds {} floats; expected 12 * joint_count = {} (joint_count {})",
                    palette.size(), expected, joint_count));
  }
  for (std::size_t i = 0; i < palette.size(); ++i) {
    if (!std::isfinite(palette[i])) {
      const std::size_t element = i % kFloatsPerJoint;
      return InvalidArgument(fmt::format("palette[joint {}][row {}, col {}] = {} is not finite",
                                         i / kFloatsPerJoint, element / 4, element % 4,
                                         palette[i]));
    }
  }
  return Status::Ok();
}

Status ValidateRigidPalette(std::span<const float> palette) {
  const std::size_t joints = palette.size() / kFloatsPerJoint;
  for (std::size_t j = 0; j < joints; ++j) {
    const float* m = palette.data() + kFloatsPerJoint * j;
    // Column c of the upper 3x3 is (m[c], m[4 + c], m[8 + c]).
    double col[3][3];
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) col[c][r] = m[4 * r + c];
    }
    auto dot = [&](int a, int b) {
      return col[a][0] * col[b][0] + col[a][1] * col[b][1] + col[a][2] * col[b][2];
    };
    auto rule = [] {
      return fmt::format(
          "dual-quaternion skinning needs rigid joint matrices (rotation and translation: "
          "every element of R^T R - I within {}, det R > 0)",
          kRigidTolerance);
    };
    for (int a = 0; a < 3; ++a) {
      for (int b = a + 1; b < 3; ++b) {
        const double d = dot(a, b);
        if (std::fabs(d) > kRigidTolerance) {
          return InvalidArgument(
              fmt::format("palette[joint {}] is not rigid: columns {} and {} have dot product "
                          "{:.6g} (shear); {}",
                          j, a, b, d, rule()));
        }
      }
    }
    for (int c = 0; c < 3; ++c) {
      const double squared = dot(c, c);
      if (std::fabs(squared - 1.0) > kRigidTolerance) {
        return InvalidArgument(
            fmt::format("palette[joint {}] is not rigid: column {} has length {:.6g} "
                        "(scale); {}",
                        j, c, std::sqrt(squared), rule()));
      }
    }
    // det R = c0 . (c1 x c2).
    const double det = col[0][0] * (col[1][1] * col[2][2] - col[1][2] * col[2][1]) +
                       col[0][1] * (col[1][2] * col[2][0] - col[1][0] * col[2][2]) +
                       col[0][2] * (col[1][0] * col[2][1] - col[1][1] * col[2][0]);
    if (det <= 0) {
      return InvalidArgument(fmt::format(
          "palette[joint {}] is not rigid: det R = {:.6g} (a reflection); {}", j, det, rule()));
    }
  }
  return Status::Ok();
}

}  // namespace skinserve
