#include "skinserve/animation/palette_job.h"

#include <fmt/format.h>

#include "affine.h"

namespace skinserve::animation {
namespace {

// palette[p] = model[joints[p]] * inverse_bind[p], compiled for each ISA (isa_clones.h).
SKINSERVE_ALWAYS_INLINE void PaletteBody(const Skeleton& skeleton, std::span<const Affine> model,
                                         float* palette) {
  const std::size_t n = skeleton.palette_size();
  for (std::size_t p = 0; p < n; ++p) {
    const float* a = model[skeleton.palette_joints[p]].m;
    const float* b = skeleton.inverse_bind[p].m;
    const detail::F4 b0 = detail::Load4(b), b1 = detail::Load4(b + 4), b2 = detail::Load4(b + 8);
    float* out = &palette[12 * p];
    // The model's rows loaded whole, their lanes broadcast by shuffles (fewer loads).
    detail::Store4(MultiplyAffineRow(detail::Load4(a), b0, b1, b2), out);
    detail::Store4(MultiplyAffineRow(detail::Load4(a + 4), b0, b1, b2), out + 4);
    detail::Store4(MultiplyAffineRow(detail::Load4(a + 8), b0, b1, b2), out + 8);
  }
}

void PaletteBaseline(const Skeleton& skeleton, std::span<const Affine> model, float* palette) {
  PaletteBody(skeleton, model, palette);
}

#if SKINSERVE_HAS_AVX2_FMA_CLONES
SKINSERVE_AVX2_FMA void PaletteAvx2Fma(const Skeleton& skeleton, std::span<const Affine> model,
                                       float* palette) {
  PaletteBody(skeleton, model, palette);
}
#endif

}  // namespace

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
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  if (detail::RunAvx2Fma()) {
    PaletteAvx2Fma(*skeleton, model, palette.data());
    return Status::Ok();
  }
#endif
  PaletteBaseline(*skeleton, model, palette.data());
  return Status::Ok();
}

}  // namespace skinserve::animation
