#include "skinserve/reference/synthetic_morph.h"

#include <algorithm>
#include <numeric>

#include "splitmix_random.h"

namespace skinserve {
namespace {

using synthetic::Random;

}  // namespace

void AddSyntheticMorphTargets(const SyntheticMorphSpec& spec, MeshArrays* arrays) {
  Random random(spec.seed * 0x2545f4914f6cdd1dull + 7);
  const bool normals = spec.normals && !arrays->normals.empty();
  const bool tangents = spec.tangents && !arrays->tangents.empty();
  Random tangent_random(spec.seed * 0x9e3779b97f4a7c15ull + 11);
  arrays->morph_tangent_deltas.clear();
  arrays->morph_target_sizes.clear();
  arrays->morph_indices.clear();
  arrays->morph_position_deltas.clear();
  arrays->morph_normal_deltas.clear();
  for (uint32_t t = 0; t < spec.targets; ++t) {
    uint32_t size = 0;
    for (uint32_t v = 0; v < arrays->vertex_count; ++v) {
      if (random.Uniform() >= spec.fraction) continue;
      ++size;
      arrays->morph_indices.push_back(v);
      for (int a = 0; a < 3; ++a)
        arrays->morph_position_deltas.push_back(static_cast<float>(random.Uniform(-0.1, 0.1)));
      if (normals) {
        for (int a = 0; a < 3; ++a)
          arrays->morph_normal_deltas.push_back(static_cast<float>(random.Uniform(-0.3, 0.3)));
      }
      if (tangents) {
        for (int a = 0; a < 3; ++a) {
          arrays->morph_tangent_deltas.push_back(
              static_cast<float>(tangent_random.Uniform(-0.3, 0.3)));
        }
      }
    }
    arrays->morph_target_sizes.push_back(size);
  }
}

std::vector<MorphWeight> MakeMorphWeights(uint32_t target_count, uint32_t active, uint64_t seed,
                                          uint64_t frame) {
  Random random(seed * 0x9e3779b97f4a7c15ull + frame * 0xd1b54a32d192ed03ull + 3);
  std::vector<uint32_t> order(target_count);
  std::iota(order.begin(), order.end(), 0u);
  // A partial Fisher-Yates shuffle: the first `active` are distinct and random.
  active = std::min(active, target_count);
  for (uint32_t i = 0; i < active; ++i) {
    const uint32_t j = i + static_cast<uint32_t>(random.Next() % (target_count - i));
    std::swap(order[i], order[j]);
  }
  std::vector<MorphWeight> weights;
  for (uint32_t i = 0; i < active; ++i) {
    float w = static_cast<float>(random.Uniform(-1.5, 1.5));
    if (w == 0.0f) w = 0.5f;
    weights.push_back({order[i], w});
  }
  return weights;
}

}  // namespace skinserve
