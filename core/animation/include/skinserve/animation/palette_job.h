// PaletteJob: the skinning palette, palette[p] = model[palette_joints[p]] * inverse_bind[p],
// 12 floats per entry, row-major 3x4: the layout SkinRequest.palette carries.
#pragma once

#include <span>

#include "skinserve/animation/skeleton.h"
#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

struct PaletteJob {
  const Skeleton* skeleton = nullptr;
  std::span<const Affine> model;  // joint_count()
  std::span<float> palette;       // 12 * palette_size()

  Status Validate() const;
  Status Run() const;
};

}  // namespace skinserve::animation
