// AddMorphDeltas (morph_delta_kernel.h) per Highway target. The masked three-lane path is
// taken on AVX-512 only: AVX2's masked store (vmaskmovps) is microcoded on some AMD cores,
// and on 128-bit targets a three-lane store is three stores again.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "backends/common/morph_delta_kernel.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include "backends/simd/simd_kernel_targets.h"
// Order matters: foreach_target.h first, then highway.h.
#include <hwy/highway.h>

#include "backends/common/morph_delta_kernel.h"

HWY_BEFORE_NAMESPACE();
namespace skinserve::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// out[0..2] += w * delta[0..2]
HWY_INLINE void AddScaled3(float w, const float* HWY_RESTRICT delta, float* HWY_RESTRICT out) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3
  const hn::FixedTag<float, 4> d;
  const auto lanes = hn::FirstN(d, 3);
  hn::BlendedStore(
      hn::MulAdd(hn::Set(d, w), hn::MaskedLoad(lanes, d, delta), hn::MaskedLoad(lanes, d, out)),
      lanes, d, out);
#else
  out[0] += w * delta[0];
  out[1] += w * delta[1];
  out[2] += w * delta[2];
#endif
}

template <bool Normals, bool Tangents>
const uint32_t* AddRun(const MorphDeltaRun& run) {
  const uint32_t* HWY_RESTRICT k = run.next;
  const uint32_t* const end = run.end;  // locals: the stores could alias `run`
  const std::size_t first = run.first, last = run.last;
  const float w = run.weight;
  const float* HWY_RESTRICT dp = run.position_deltas;
  const float* HWY_RESTRICT dn = run.normal_deltas;
  const float* HWY_RESTRICT dt = run.tangent_deltas;
  float* HWY_RESTRICT p = run.positions;
  float* HWY_RESTRICT n = run.normals;
  float* HWY_RESTRICT t = run.tangents;
  for (; k != end && *k < last; ++k) {
    const std::size_t v = *k - first;
    AddScaled3(w, dp, p + 3 * v);
    dp += 3;
    if constexpr (Normals) {
      AddScaled3(w, dn, n + 3 * v);
      dn += 3;
    }
    if constexpr (Tangents) {
      AddScaled3(w, dt, t + 4 * v);  // xyz; w is never morphed
      dt += 3;
    }
  }
  return k;
}

const uint32_t* AddMorphDeltasTarget(const MorphDeltaRun& run) {
  if (run.tangent_deltas != nullptr) {
    return run.normal_deltas != nullptr ? AddRun<true, true>(run) : AddRun<false, true>(run);
  }
  return run.normal_deltas != nullptr ? AddRun<true, false>(run) : AddRun<false, false>(run);
}

}  // namespace skinserve::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace skinserve {

HWY_EXPORT(AddMorphDeltasTarget);

const uint32_t* AddMorphDeltas(const MorphDeltaRun& run) {
  return HWY_DYNAMIC_DISPATCH(AddMorphDeltasTarget)(run);
}

}  // namespace skinserve
#endif  // HWY_ONCE
