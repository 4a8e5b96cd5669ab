// ModelErrorCheck: the builder's float64 model-space evaluation of a clip's joint tracks
// over its skeleton, against the same evaluation of the original channels. It tells
// whether a track stored another way (fewer bits) keeps every joint, at every key time and
// halfway between, within the clip's bound (compact_clip.h): position within
// share * (max_error + kRelativeError |position|), each row of the 3x3 part (so each
// element of the model matrix and of its palette entries) within
// share * max_error / kShellDistanceMm. `share` < 1 leaves room for the sampler's float32.
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"

namespace skinserve::animation::detail {

// A joint track as the sampler will see it: RawTrack's layout (CUBICSPLINE: in-tangent,
// value, out-tangent a key) with the values the store decodes to. `times` points into the
// RawClip (or at one 0 for a constant).
struct StoredJointTrack {
  TrackPath path = TrackPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  uint32_t joint = 0;
  const std::vector<float>* times = nullptr;
  std::vector<float> values;
};

class ModelErrorCheck {
 public:
  // `stored`: every joint track as stored now (a joint's others sample its rest).
  ModelErrorCheck(const Skeleton& skeleton, const RawClip& raw,
                  std::vector<StoredJointTrack> stored, double max_error_mm, double share);

  // Joint-samples (joints x evaluated times) the check would hold: the builder keeps 16
  // bits rather than evaluate more than kMaxJointSamples.
  static std::size_t JointSamples(const Skeleton& skeleton, const RawClip& raw);
  static constexpr std::size_t kMaxJointSamples = 200000;

  // True when stored track `i` with `values` instead keeps every joint within the bound.
  bool Holds(std::size_t i, const std::vector<float>& values) const;
  // Stored track `i` is now `values`.
  void Accept(std::size_t i, std::vector<float> values);

 private:
  using Matrix = std::vector<double>;  // 12 doubles a joint-sample: 3x4 row-major

  void LocalOf(uint32_t joint, double t, std::size_t replaced, const std::vector<float>* values,
               double out[12]) const;
  // Model matrices of `joint`'s subtree at time index `ti` with its local `local`, into
  // `model` (joints x 12); false at the first joint outside the bound when `check`.
  bool Subtree(uint32_t joint, std::size_t ti, const double local[12], double* model,
               bool check) const;

  const Skeleton& skeleton_;
  std::vector<StoredJointTrack> stored_;
  std::vector<std::vector<uint32_t>> joint_tracks_;  // per joint: indices into stored_
  std::vector<std::vector<uint32_t>> subtree_;       // per joint: its descendants, in order
  std::vector<double> times_;
  Matrix reference_, local_, model_;  // [time][joint][12]
  double position_bound_, relative_bound_, rotation_bound_;
  std::vector<double> stretch_;  // per joint: PaletteStretch
};

}  // namespace skinserve::animation::detail
