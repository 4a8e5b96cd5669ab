// CompactClip: a clip stored for sampling, at a quarter of glTF's float bytes or less
// where tracks repeat keys (constant tracks, shared key times), with a stated error bound.
//
// How each track is stored (TrackFormat) and the error of a stored key against the float
// key it came from (the bound; tests/animation/compact_clip_test.cpp checks it):
//  - left out: a joint's track whose every key is within kConstantTolerance (as kConstant)
//    of the skeleton's rest value (a bone's length, a scale of 1): the joint samples its rest.
//  - kConstant: every key within kConstantTolerance (relative to max(1, |value|), or that
//    angle in radians for rotations) of the first: one float value, no times.
//  - kRange16: each component 16-bit quantized against the track's range [min, max] of
//    that component: |error| <= (max - min) / 131070 (plus float rounding). Translation,
//    scale, morph weights, and every CUBICSPLINE track (values and tangents).
//  - kSmallestThree16: LINEAR and STEP rotations: the largest component's index (2 bits,
//    made positive) and the other three, each 16-bit quantized against its range over the
//    track (within [-1/sqrt2, 1/sqrt2]): each within e = range / 131070 <= 1.079e-5, the
//    rotation within kRotationKeyErrorRadians of the key's (less for a joint turning little).
// Times are exact: every key time of the clip is stored once (float32, `times`); a track
// keyed at every one of them stores no times, any other stores a 16-bit index per key.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

inline constexpr float kConstantTolerance = 1e-6f;
// Each stored component within e <= 1.079e-5 (a range of at most sqrt2 in 65535 steps);
// the rebuilt largest within 3e (it is >= 1/2), |dq| <= sqrt(12) e, angle <= 2 |dq|.
inline constexpr float kRotationKeyErrorRadians = 7.5e-5f;
inline constexpr uint32_t kMaxClipKeyTimes = 65535;  // indices are 16-bit
inline constexpr uint32_t kAllKeyTimes = 0xffffffffu;

struct SamplingPlan;  // core/animation/src/sampling_plan.h

enum class TrackFormat : uint8_t { kConstant, kRange16, kSmallestThree16 };

struct CompactTrack {
  TrackPath path = TrackPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  TrackFormat format = TrackFormat::kConstant;
  uint16_t width = 0;          // floats a value
  uint16_t joint = 0;          // translation, rotation, scale: the skeleton joint
  uint32_t weight_offset = 0;  // weights: where its `width` floats go in the sampled weights
  uint32_t key_count = 0;
  uint32_t key_times = kAllKeyTimes;  // offset into CompactClip::key_times, or every time
  uint32_t floats = 0;   // offset into CompactClip::floats: the constant, or (min, step) pairs
  uint32_t words = 0;    // offset into CompactClip::words: the quantized keys
  uint32_t largest = 0;  // kSmallestThree16: first key's 2-bit slot in CompactClip::largest
};

struct CompactClip {
  std::string name;
  float duration = 0;
  uint32_t joint_count = 0;             // of the skeleton it was built for
  uint32_t weight_count = 0;            // floats of morph weights a sample writes
  std::vector<uint32_t> weight_groups;  // per weights track, in order: RawTrack::target
  std::vector<float> times;             // every key time, increasing
  std::vector<uint16_t> key_times;
  std::vector<CompactTrack> tracks;
  std::vector<float> floats;
  std::vector<uint16_t> words;
  std::vector<uint8_t> largest;  // smallest-three: 4 two-bit indices a byte
  std::string id;                // SHA-256 of Serialize(), lowercase hex
  // How SamplingJob walks the tracks (which it takes 4 at a time), made by
  // BuildCompactClip from the fields above; not part of the bytes. A clip without one
  // samples one track at a time.
  std::shared_ptr<const SamplingPlan> plan;

  // The canonical little-endian bytes: what the id hashes and what the clip costs.
  std::vector<uint8_t> Serialize() const;
};

// INVALID_ARGUMENT naming the track and field: targets in the skeleton, widths, times
// finite, >= 0 and increasing, values finite, counts matching, CUBICSPLINE with 2+ keys.
Result<CompactClip> BuildCompactClip(const RawClip& raw, const Skeleton& skeleton);

}  // namespace skinserve::animation
