#include "skinserve/animation/blending_job.h"

#include <fmt/format.h>

#include <cmath>

#include "float4.h"
#include "quaternion.h"

namespace skinserve::animation {
namespace {

// A Transform's 10 floats as three overlapping 4-float loads: t xyz + qx, q xyzw, qw + s xyz.
// Stored back translation, then scale, then rotation, the rotation's lanes win the overlap.
SKINSERVE_ALWAYS_INLINE void BlendNormalBody(std::span<const BlendLayer> layers, float total,
                                             std::span<Transform> out) {
  using detail::F4;
  const float* pose[kMaxBlendLayers];
  float weight[kMaxBlendLayers];
  std::size_t n = 0;
  for (const BlendLayer& l : layers) {
    if (l.additive || l.weight <= 0) continue;
    pose[n] = l.pose.data()->translation;
    weight[n++] = l.weight / total;
  }
  F4 w[kMaxBlendLayers];
  for (std::size_t i = 0; i < n; ++i) w[i] = detail::Splat(weight[i]);
  static_assert(sizeof(Transform) == 10 * sizeof(float));
  for (std::size_t j = 0; j < out.size(); ++j) {
    // The first layer as it is (its rotation is the hemisphere's reference).
    const float* first = pose[0] + 10 * j;
    const F4 reference = detail::Load4(first + 3);
    F4 t = w[0] * detail::Load4(first), q = w[0] * reference, s = w[0] * detail::Load4(first + 6);
    for (std::size_t i = 1; i < n; ++i) {
      const float* f = pose[i] + 10 * j;
      const F4 rotation = detail::Load4(f + 3);
      // The shortest path: a quaternion on the other hemisphere than the first layer's
      // is the same rotation negated.
      const F4 wq = detail::NegateWhereNegative(w[i], detail::Dot(reference, rotation));
      t = t + w[i] * detail::Load4(f);
      q = q + wq * rotation;
      s = s + w[i] * detail::Load4(f + 6);
    }
    q = q * detail::InverseSqrt(detail::Dot(q, q));
    float* o = out[j].translation;
    detail::Store4(t, o);
    detail::Store4(s, o + 6);
    detail::Store4(q, o + 3);
  }
}

void BlendNormalBaseline(std::span<const BlendLayer> layers, float total,
                         std::span<Transform> out) {
  BlendNormalBody(layers, total, out);
}

#if SKINSERVE_HAS_AVX2_FMA_CLONES
SKINSERVE_AVX2_FMA void BlendNormalAvx2Fma(std::span<const BlendLayer> layers, float total,
                                           std::span<Transform> out) {
  BlendNormalBody(layers, total, out);
}
#endif

// The normal layers' weighted mean, compiled for each ISA (isa_clones.h).
void BlendNormal(std::span<const BlendLayer> layers, float total, std::span<Transform> out) {
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  if (detail::RunAvx2Fma()) return BlendNormalAvx2Fma(layers, total, out);
#endif
  BlendNormalBaseline(layers, total, out);
}

void ApplyAdditive(const BlendLayer& l, std::span<Transform> out) {
  const float w = l.weight;
  for (std::size_t j = 0; j < out.size(); ++j) {
    const Transform& a = l.pose[j];
    Transform& t = out[j];
    float q[4];  // nlerp(identity, a, w), on a's shortest path from identity
    const float sign = a.rotation[3] < 0 ? -1.0f : 1.0f;
    for (int c = 0; c < 3; ++c) q[c] = sign * w * a.rotation[c];
    q[3] = (1 - w) + sign * w * a.rotation[3];
    detail::Normalize4(q);
    float r[4];
    detail::Multiply(q, t.rotation, r);
    for (int c = 0; c < 4; ++c) t.rotation[c] = r[c];
    for (int c = 0; c < 3; ++c) {
      t.translation[c] += w * a.translation[c];
      t.scale[c] *= 1 + w * (a.scale[c] - 1);
    }
  }
}

// output = sum over layers of w * morph_weights, w the normal layers' weight / total or the
// additive layers' weight; a layer's empty morph_weights count as zeros.
void AccumulateMorph(std::span<const BlendLayer> layers, float total, std::span<float> output) {
  for (float& m : output) m = 0;
  for (const BlendLayer& l : layers) {
    if (l.morph_weights.empty()) continue;
    const float w = l.additive ? l.weight : l.weight / total;
    for (std::size_t i = 0; i < output.size(); ++i) output[i] += w * l.morph_weights[i];
  }
}

}  // namespace

Status BlendMorphWeights(std::span<const BlendLayer> layers, std::span<float> output) {
  if (layers.empty() || layers.size() > kMaxBlendLayers) {
    return InvalidArgument(fmt::format("morph blending: {} layers; 1..{} are supported",
                                       layers.size(), kMaxBlendLayers));
  }
  float total = 0;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const BlendLayer& l = layers[i];
    if (!std::isfinite(l.weight) || l.weight < 0) {
      return InvalidArgument(fmt::format(
          "morph blending: layers[{}].weight is {}; weights are finite and >= 0", i, l.weight));
    }
    if (!l.morph_weights.empty() && l.morph_weights.size() != output.size()) {
      return InvalidArgument(
          fmt::format("morph blending: layers[{}].morph_weights has {} floats; output has {}", i,
                      l.morph_weights.size(), output.size()));
    }
    if (!l.additive) total += l.weight;
  }
  if (!(total > 0)) {
    return InvalidArgument(
        "morph blending: the non-additive layers' weights sum to 0; at least one needs "
        "weight > 0");
  }
  AccumulateMorph(layers, total, output);
  return Status::Ok();
}

Status BlendingJob::Validate() const {
  if (layers.empty() || layers.size() > kMaxBlendLayers) {
    return InvalidArgument(
        fmt::format("blending: {} layers; 1..{} are supported", layers.size(), kMaxBlendLayers));
  }
  float total = 0;
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const BlendLayer& l = layers[i];
    if (!std::isfinite(l.weight) || l.weight < 0) {
      return InvalidArgument(fmt::format(
          "blending: layers[{}].weight is {}; weights are finite and >= 0", i, l.weight));
    }
    if (l.pose.size() != output.size()) {
      return InvalidArgument(
          fmt::format("blending: layers[{}].pose has {} transforms; output has {}", i,
                      l.pose.size(), output.size()));
    }
    if (!morph_weights.empty() && l.morph_weights.size() != morph_weights.size()) {
      return InvalidArgument(
          fmt::format("blending: layers[{}].morph_weights has {} floats; output has {}", i,
                      l.morph_weights.size(), morph_weights.size()));
    }
    if (!l.additive) total += l.weight;
  }
  if (!(total > 0)) {
    return InvalidArgument(
        "blending: the non-additive layers' weights sum to 0; at least one needs weight > 0");
  }
  return Status::Ok();
}

Status BlendingJob::Run() const {
  if (Status s = Validate(); !s.ok()) return s;
  float total = 0;
  for (const BlendLayer& l : layers) total += l.additive ? 0 : l.weight;
  BlendNormal(layers, total, output);
  for (const BlendLayer& l : layers) {
    if (l.additive && l.weight > 0) ApplyAdditive(l, output);
  }
  AccumulateMorph(layers, total, morph_weights);
  return Status::Ok();
}

}  // namespace skinserve::animation
