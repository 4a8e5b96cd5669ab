#include "skinserve/animation/local_to_model_job.h"

#include <fmt/format.h>

#include "affine.h"

namespace skinserve::animation {
namespace {

// T * R * S as a row-major 3x4.
Affine ToAffine(const Transform& t) {
  const float x = t.rotation[0], y = t.rotation[1], z = t.rotation[2], w = t.rotation[3];
  const float xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z;
  const float wx = w * x, wy = w * y, wz = w * z;
  const float* s = t.scale;
  Affine a;
  float* m = a.m;
  m[0] = (1 - 2 * (yy + zz)) * s[0];
  m[1] = 2 * (xy - wz) * s[1];
  m[2] = 2 * (xz + wy) * s[2];
  m[3] = t.translation[0];
  m[4] = 2 * (xy + wz) * s[0];
  m[5] = (1 - 2 * (xx + zz)) * s[1];
  m[6] = 2 * (yz - wx) * s[2];
  m[7] = t.translation[1];
  m[8] = 2 * (xz - wy) * s[0];
  m[9] = 2 * (yz + wx) * s[1];
  m[10] = (1 - 2 * (xx + yy)) * s[2];
  m[11] = t.translation[2];
  return a;
}

}  // namespace

Status LocalToModelJob::Validate() const {
  if (skeleton == nullptr) return InvalidArgument("local-to-model: skeleton is missing");
  const std::size_t n = skeleton->joint_count();
  if (local.size() != n || model.size() != n) {
    return InvalidArgument(fmt::format(
        "local-to-model: local has {} transforms and model {} matrices; the skeleton has {} joints",
        local.size(), model.size(), n));
  }
  return Status::Ok();
}

Status LocalToModelJob::Run() const {
  if (Status s = Validate(); !s.ok()) return s;
  const std::size_t n = local.size();
  for (std::size_t i = 0; i < n; ++i) {
    const int parent = skeleton->parents[i];
    if (parent < 0) {
      model[i] = ToAffine(local[i]);
    } else {
      MultiplyAffine(model[static_cast<std::size_t>(parent)], ToAffine(local[i]), model[i]);
    }
  }
  return Status::Ok();
}

}  // namespace skinserve::animation
