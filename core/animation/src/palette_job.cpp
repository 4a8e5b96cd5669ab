#include "skinserve/animation/palette_job.h"

#include <fmt/format.h>

#include "affine.h"

namespace skinserve::animation {

Status PaletteJob::Validate() const {
  if (skeleton == nullptr) return InvalidArgument("palette: skeleton is missing");
  if (model.size() != skeleton->joint_count()) {
    return InvalidArgument(fmt::format("palette: model has {} matrices; the skeleton has {} joints",
                                       model.size(), skeleton->joint_count()));
  }
  if (palette.size() != 12ull * skeleton->palette_size()) {
    return InvalidArgument(fmt::format("palette: palette has {} floats; {} entries need {}",
                                       palette.size(), skeleton->palette_size(),
                                       12ull * skeleton->palette_size()));
  }
  return Status::Ok();
}

Status PaletteJob::Run() const {
  if (Status s = Validate(); !s.ok()) return s;
  const std::size_t n = skeleton->palette_size();
  for (std::size_t p = 0; p < n; ++p) {
    MultiplyAffine(model[skeleton->palette_joints[p]].m, skeleton->inverse_bind[p].m,
                   &palette[12 * p]);
  }
  return Status::Ok();
}

}  // namespace skinserve::animation
