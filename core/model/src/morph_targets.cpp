#include "skinserve/model/morph_targets.h"

#include <fmt/format.h>

#include <bitset>
#include <cmath>

namespace skinserve {

Status ValidateMorphWeights(std::span<const MorphWeight> weights, uint32_t target_count) {
  if (weights.size() > kMaxMorphTargets) {
    return InvalidArgument(
        fmt::format("morph_weights holds {} entries; at most {} (one per target)", weights.size(),
                    kMaxMorphTargets));
  }
  std::bitset<kMaxMorphTargets> seen;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const MorphWeight& w = weights[i];
    if (w.target >= target_count) {
      return InvalidArgument(
          fmt::format("morph_weights[{}]: target {} is not below the mesh's morph_target_count {}",
                      i, w.target, target_count));
    }
    if (seen.test(w.target)) {
      return InvalidArgument(fmt::format(
          "morph_weights[{}]: target {} is listed twice; list each target once", i, w.target));
    }
    seen.set(w.target);
    if (!std::isfinite(w.weight) || std::fabs(w.weight) > kMaxMorphWeight) {
      return InvalidArgument(
          fmt::format("morph_weights[{}]: weight {} of target {} must be finite and within +-{}", i,
                      w.weight, w.target, kMaxMorphWeight));
    }
  }
  return Status::Ok();
}

bool HasActiveMorph(std::span<const MorphWeight> weights) {
  for (const MorphWeight& w : weights) {
    if (w.weight != 0.0f) return true;
  }
  return false;
}

}  // namespace skinserve
