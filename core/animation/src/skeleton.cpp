#include "skinserve/animation/skeleton.h"

#include <fmt/format.h>

#include <cmath>

namespace skinserve::animation {
namespace {

bool Finite(const float* v, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) return false;
  }
  return true;
}

Status ValidateRest(const Skeleton& s) {
  for (std::size_t i = 0; i < s.rest.size(); ++i) {
    const Transform& t = s.rest[i];
    if (!Finite(t.translation, 3) || !Finite(t.rotation, 4) || !Finite(t.scale, 3)) {
      return InvalidArgument(fmt::format("skeleton.rest[{}] is not finite", i));
    }
    const double length =
        std::sqrt(double{t.rotation[0]} * t.rotation[0] + double{t.rotation[1]} * t.rotation[1] +
                  double{t.rotation[2]} * t.rotation[2] + double{t.rotation[3]} * t.rotation[3]);
    if (std::fabs(length - 1.0) > 1e-3) {
      return InvalidArgument(fmt::format(
          "skeleton.rest[{}].rotation has length {}; a rotation is a unit quaternion", i, length));
    }
  }
  return Status::Ok();
}

}  // namespace

Status ValidateSkeleton(const Skeleton& s) {
  const std::size_t n = s.parents.size();
  if (n == 0 || n > kMaxSkeletonJoints) {
    return InvalidArgument(
        fmt::format("skeleton.parents has {} joints; 1..{} are supported", n, kMaxSkeletonJoints));
  }
  for (std::size_t i = 0; i < n; ++i) {
    const int parent = s.parents[i];
    if (parent < -1 || parent >= static_cast<int>(i)) {
      return InvalidArgument(fmt::format(
          "skeleton.parents[{}] = {}; a parent comes before its child (-1 for a root)", i, parent));
    }
  }
  if (s.rest.size() != n) {
    return InvalidArgument(
        fmt::format("skeleton.rest has {} transforms for {} joints", s.rest.size(), n));
  }
  if (!s.names.empty() && s.names.size() != n) {
    return InvalidArgument(
        fmt::format("skeleton.names has {} names for {} joints", s.names.size(), n));
  }
  if (Status st = ValidateRest(s); !st.ok()) return st;
  if (s.inverse_bind.size() != s.palette_joints.size()) {
    return InvalidArgument(
        fmt::format("skeleton.inverse_bind has {} matrices for {} palette joints",
                    s.inverse_bind.size(), s.palette_joints.size()));
  }
  for (std::size_t p = 0; p < s.palette_joints.size(); ++p) {
    if (s.palette_joints[p] >= n) {
      return InvalidArgument(
          fmt::format("skeleton.palette_joints[{}] = {} is not a joint (there are {})", p,
                      s.palette_joints[p], n));
    }
    if (!Finite(s.inverse_bind[p].m, 12)) {
      return InvalidArgument(fmt::format("skeleton.inverse_bind[{}] is not finite", p));
    }
  }
  return Status::Ok();
}

}  // namespace skinserve::animation
