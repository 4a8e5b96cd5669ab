#include "track_bits.h"

#include <algorithm>
#include <numeric>

#include "model_error_check.h"
#include "skinserve/animation/compact_clip.h"
#include "track_quantizer.h"

namespace skinserve::animation::detail {
namespace {

// Of the model-space bound, what quantization may take: the rest is left for the sampler's
// float32 (Eberly's slerp series, within 5e-7 rad; float matrices), which the builder's
// float64 evaluation does not see. The tests hold the sampled poses to the whole bound.
constexpr double kQuantizationShare = 0.9;

const std::vector<float> kTimeZero = {0.0f};

// Each joint track as the store keeps it with 16 bits; `stored_of[i]`: raw track i's
// index among them (or -1: left out, or weights).
std::vector<StoredJointTrack> StoredAt16(const RawClip& raw, const std::vector<TrackKind>& kinds,
                                         std::vector<int>& stored_of) {
  std::vector<StoredJointTrack> stored;
  stored_of.assign(raw.tracks.size(), -1);
  for (std::size_t i = 0; i < raw.tracks.size(); ++i) {
    const RawTrack& t = raw.tracks[i];
    if (t.path == TrackPath::kWeights || kinds[i] == TrackKind::kAtRest) continue;
    StoredJointTrack s{t.path, t.interpolation, t.target, &t.times, {}};
    if (kinds[i] == TrackKind::kConstant) {
      const std::size_t first = t.interpolation == Interpolation::kCubicSpline ? t.width : 0;
      s.interpolation = Interpolation::kLinear;
      s.times = &kTimeZero;
      s.values.assign(t.values.begin() + static_cast<std::ptrdiff_t>(first),
                      t.values.begin() + static_cast<std::ptrdiff_t>(first + t.width));
    } else if (kinds[i] == TrackKind::kCandidate) {
      s.values = QuantizeTrack(t, 16).decoded;
    } else {
      s.values = DecodedRange16(t);
    }
    stored_of[i] = static_cast<int>(stored.size());
    stored.push_back(std::move(s));
  }
  return stored;
}

}  // namespace

std::vector<uint32_t> ChooseTrackBits(const RawClip& raw, const Skeleton& skeleton,
                                      const std::vector<TrackKind>& kinds, double max_error_mm) {
  std::vector<uint32_t> bits(raw.tracks.size(), 16);
  // The default bound keeps 16 bits: packed keys save CesiumMan 11% of its bytes at
  // 0.01 mm but cost BM_Pose 5-10% (docs/serving/animation-runtime.md#size); too long a
  // clip to evaluate keeps them too.
  if (max_error_mm <= kDefaultMaxErrorMm ||
      ModelErrorCheck::JointSamples(skeleton, raw) > ModelErrorCheck::kMaxJointSamples) {
    return bits;
  }
  std::vector<int> stored_of;
  ModelErrorCheck check(skeleton, raw, StoredAt16(raw, kinds, stored_of), max_error_mm,
                        kQuantizationShare);
  std::vector<std::size_t> order(raw.tracks.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return raw.tracks[a].target > raw.tracks[b].target;  // leaves first
  });
  for (std::size_t i : order) {
    if (kinds[i] != TrackKind::kCandidate) continue;
    const std::size_t s = static_cast<std::size_t>(stored_of[i]);
    // The check starts from 16 bits; each `hi` below it was checked (its values in `best`).
    uint32_t lo = kMinPackedBits, hi = 16;
    std::vector<float> best;
    while (lo < hi) {
      const uint32_t mid = (lo + hi) / 2;
      std::vector<float> values = QuantizeTrack(raw.tracks[i], mid).decoded;
      if (check.Holds(s, values)) {
        hi = mid;
        best = std::move(values);
      } else {
        lo = mid + 1;
      }
    }
    if (hi < 16) {
      check.Accept(s, std::move(best));
      bits[i] = hi;
    }
  }
  return bits;
}

}  // namespace skinserve::animation::detail
