// LocalToModelJob: model-space matrices from local poses, root down in one pass
// (parents come before children): model[i] = model[parent] * T * R * S.
#pragma once

#include <span>

#include "skinserve/animation/skeleton.h"
#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

struct LocalToModelJob {
  const Skeleton* skeleton = nullptr;
  std::span<const Transform> local;  // joint_count()
  std::span<Affine> model;           // joint_count()

  Status Validate() const;
  Status Run() const;
};

}  // namespace skinserve::animation
