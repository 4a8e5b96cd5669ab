// RawClip: a clip as glTF states it (float keys, per-track times), the input of
// BuildCompactClip. Tracks target skeleton joints (translation, rotation, scale) or a
// group of morph weights (weights: `width` floats a key).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace skinserve::animation {

enum class TrackPath : uint8_t { kTranslation, kRotation, kScale, kWeights };
enum class Interpolation : uint8_t { kStep, kLinear, kCubicSpline };

struct RawTrack {
  TrackPath path = TrackPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  // Skeleton joint for translation, rotation and scale; for weights, the morph group
  // (the caller's numbering, e.g. a glTF node), echoed in CompactClip::weight_groups.
  uint32_t target = 0;
  uint32_t width = 0;         // floats a value: 3, 4 (x y z w), or the weights' count
  std::vector<float> times;   // strictly increasing seconds, >= 0
  std::vector<float> values;  // per key `width` floats; CUBICSPLINE: in-tangent, value, out-tangent
};

struct RawClip {
  std::string name;
  float duration = 0;  // seconds; at least the last key time
  std::vector<RawTrack> tracks;
};

}  // namespace skinserve::animation
