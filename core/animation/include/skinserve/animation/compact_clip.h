// CompactClip: a clip stored for sampling with a stated error bound chosen at build time
// (ClipBuildOptions::max_error_mm), checked in model space against a float64 evaluation of
// the original channels.
//
// How each track is stored (TrackFormat) and the error of a stored key against the float
// key it came from (tests/animation/compact_clip_test.cpp checks it):
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
//  - kRangePacked, kSmallestThreePacked: as the two above with `bits` (4..15) a component,
//    bit-packed (key k's components at bits [k * components * bits, ...) of the track's
//    bytes): |error| <= range / (2 (2^bits - 1)). Chosen per LINEAR or STEP translation,
//    rotation and scale track, for a bound looser than the default, when the model-space
//    check below still holds with it (at the default every track keeps 16 bits: the
//    sampler decodes those fastest).
// The model-space bound (ClipBuildOptions): with every track as stored, every joint's
// model-space position within max_error_mm + kRelativeError |position| and each row of its
// 3x3 (so each element, of it and of its palette entries) within max_error_mm /
// kShellDistanceMm of a float64 evaluation of the original channels, at every key time,
// halfway between and (with STEP tracks) just before each key; the builder evaluates it
// with 10% left for the sampler's float32. Lengths are taken in metres (glTF's unit).
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

// The error a clip is built to (ClipBuildOptions::max_error_mm): 0 means the default, the
// issue's 0.01 mm; others must lie in [kMinMaxErrorMm, kMaxMaxErrorMm].
inline constexpr float kDefaultMaxErrorMm = 0.01f;
inline constexpr float kMinMaxErrorMm = 0.01f;
inline constexpr float kMaxMaxErrorMm = 10.0f;
inline constexpr double kRelativeError = 1e-4;  // of the joint's distance from the origin
// A rotation error e moves a vertex this far from its joint by about e times the distance:
// 3x3 elements are held to max_error / kShellDistanceMm (1e-4 at the default).
inline constexpr double kShellDistanceMm = 100.0;
inline constexpr uint32_t kMinPackedBits = 4;
inline constexpr std::size_t kPackedSlack = 8;  // zero bytes after packed: 64-bit reads

struct ClipBuildOptions {
  float max_error_mm = 0;  // 0: kDefaultMaxErrorMm
};

struct SamplingPlan;  // core/animation/src/sampling_plan.h

enum class TrackFormat : uint8_t {
  kConstant,
  kRange16,
  kSmallestThree16,
  kRangePacked,
  kSmallestThreePacked
};

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
  uint32_t words = 0;    // offset into CompactClip::words (16-bit formats) or byte offset
                         // into CompactClip::packed (packed formats): the quantized keys
  uint8_t bits = 16;     // a stored component's bits (packed formats: 4..15)
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
  std::vector<uint16_t> words;              // 16-bit keys
  std::vector<uint8_t> largest;             // smallest-three: 4 two-bit indices a byte
  std::vector<uint8_t> packed;              // packed formats' keys, then kPackedSlack zero bytes
  float max_error_mm = kDefaultMaxErrorMm;  // the model-space bound it was built to
  std::string id;                           // SHA-256 of Serialize(), lowercase hex
  // How SamplingJob walks the tracks (which it takes 4 at a time), made by
  // BuildCompactClip from the fields above; not part of the bytes. A clip without one
  // samples one track at a time.
  std::shared_ptr<const SamplingPlan> plan;

  // The canonical little-endian bytes: what the id hashes and what the clip costs.
  std::vector<uint8_t> Serialize() const;
};

// INVALID_ARGUMENT naming the track and field: targets in the skeleton, widths, times
// finite, >= 0 and increasing, values finite, counts matching, CUBICSPLINE with 2+ keys;
// max_error_mm outside its limits.
Result<CompactClip> BuildCompactClip(const RawClip& raw, const Skeleton& skeleton,
                                     const ClipBuildOptions& options = {});

}  // namespace skinserve::animation
