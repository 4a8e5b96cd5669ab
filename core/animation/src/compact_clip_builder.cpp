// BuildCompactClip: checks a RawClip against its skeleton, then stores each track in the
// smallest format that keeps the stated bound (compact_clip.h).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "clip_id.h"
#include "quantize.h"
#include "sampling_plan.h"
#include "skinserve/animation/compact_clip.h"
#include "track_bits.h"
#include "track_quantizer.h"

namespace skinserve::animation {
namespace {

const char* PathName(TrackPath path) {
  switch (path) {
    case TrackPath::kTranslation:
      return "translation";
    case TrackPath::kRotation:
      return "rotation";
    case TrackPath::kScale:
      return "scale";
    case TrackPath::kWeights:
      return "weights";
  }
  return "?";
}

uint32_t ExpectedWidth(TrackPath path) {
  return path == TrackPath::kRotation ? 4 : (path == TrackPath::kWeights ? 0 : 3);
}

Status ValidateTrack(const RawTrack& t, std::size_t i, const Skeleton& skeleton) {
  const std::string what = fmt::format("tracks[{}] ({})", i, PathName(t.path));
  if (t.path != TrackPath::kWeights && t.target >= skeleton.joint_count()) {
    return InvalidArgument(fmt::format("{}.target = {} is not a joint (the skeleton has {})", what,
                                       t.target, skeleton.joint_count()));
  }
  const uint32_t width = ExpectedWidth(t.path);
  if ((width != 0 && t.width != width) || t.width == 0 || t.width > 0xffff) {
    return InvalidArgument(fmt::format("{}.width = {}; expected {}", what, t.width,
                                       width != 0 ? std::to_string(width) : "1..65535"));
  }
  const bool cubic = t.interpolation == Interpolation::kCubicSpline;
  if (t.times.empty() || (cubic && t.times.size() < 2)) {
    return InvalidArgument(fmt::format("{}.times has {} keys; {} needs at least {}", what,
                                       t.times.size(), cubic ? "CUBICSPLINE" : "a track",
                                       cubic ? 2 : 1));
  }
  for (std::size_t k = 0; k < t.times.size(); ++k) {
    if (!std::isfinite(t.times[k]) || t.times[k] < 0 || (k > 0 && !(t.times[k] > t.times[k - 1]))) {
      return InvalidArgument(
          fmt::format("{}.times[{}] = {}; key times must be finite, >= 0 and strictly increasing",
                      what, k, t.times[k]));
    }
  }
  const std::size_t expected = t.times.size() * t.width * (cubic ? 3 : 1);
  if (t.values.size() != expected) {
    return InvalidArgument(fmt::format("{}.values has {} floats; {} keys need {}", what,
                                       t.values.size(), t.times.size(), expected));
  }
  for (std::size_t v = 0; v < t.values.size(); ++v) {
    if (!std::isfinite(t.values[v])) {
      return InvalidArgument(fmt::format("{}.values[{}] is not finite", what, v));
    }
  }
  return Status::Ok();
}

// True when every key is within kConstantTolerance of v0 (relative to max(1, |v0|), or that
// angle for rotations); CUBICSPLINE: and every tangent within it of 0.
bool AllKeysNear(const RawTrack& t, const float* v0) {
  const bool cubic = t.interpolation == Interpolation::kCubicSpline;
  const std::size_t w = t.width, stride = w * (cubic ? 3 : 1), first = cubic ? w : 0;
  for (std::size_t k = 0; k < t.times.size(); ++k) {
    const float* v = &t.values[k * stride + first];
    if (t.path == TrackPath::kRotation) {
      double dot = 0, l0 = 0, l1 = 0;
      for (int c = 0; c < 4; ++c) {
        dot += double{v[c]} * v0[c];
        l0 += double{v0[c]} * v0[c];
        l1 += double{v[c]} * v[c];
      }
      const double cos_half = std::min(1.0, std::fabs(dot) / std::sqrt(l0 * l1));
      if (2 * std::acos(cos_half) > kConstantTolerance) return false;
    } else {
      for (std::size_t c = 0; c < w; ++c) {
        if (std::fabs(v[c] - v0[c]) > kConstantTolerance * std::max(1.0f, std::fabs(v0[c])))
          return false;
      }
    }
    if (cubic) {
      for (std::size_t c = 0; c < w; ++c) {
        if (std::fabs(t.values[k * stride + c]) > kConstantTolerance ||
            std::fabs(t.values[k * stride + 2 * w + c]) > kConstantTolerance)
          return false;
      }
    }
  }
  return true;
}

bool IsConstant(const RawTrack& t) {
  return AllKeysNear(t, &t.values[t.interpolation == Interpolation::kCubicSpline ? t.width : 0]);
}

// A constant track at the joint's rest value samples as no track at all (the sampler starts
// from the rest): a bone's length, a scale of 1. Stored as nothing.
bool IsAtRest(const RawTrack& t, const Skeleton& skeleton) {
  if (t.path == TrackPath::kWeights) return false;
  const Transform& rest = skeleton.rest[t.target];
  const float* v0 = t.path == TrackPath::kTranslation
                        ? rest.translation
                        : (t.path == TrackPath::kRotation ? rest.rotation : rest.scale);
  return AllKeysNear(t, v0);
}

void StoreConstant(const RawTrack& t, CompactClip& clip, CompactTrack& out) {
  const std::size_t first = t.interpolation == Interpolation::kCubicSpline ? t.width : 0;
  out.format = TrackFormat::kConstant;
  out.key_count = 1;
  out.floats = static_cast<uint32_t>(clip.floats.size());
  for (std::size_t c = 0; c < t.width; ++c) clip.floats.push_back(t.values[first + c]);
  if (t.path == TrackPath::kRotation) {  // stored unit, as every sampled rotation is
    float* q = &clip.floats[out.floats];
    const float length = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int c = 0; c < 4; ++c) q[c] /= length;
  }
}

// Components in "parts" (cubic: in-tangent, value, out-tangent), each against its range.
void StoreRange16(const RawTrack& t, CompactClip& clip, CompactTrack& out) {
  const std::size_t parts = t.interpolation == Interpolation::kCubicSpline ? 3 : 1;
  const std::size_t w = t.width, columns = parts * w, keys = t.times.size();
  out.format = TrackFormat::kRange16;
  out.floats = static_cast<uint32_t>(clip.floats.size());
  out.words = static_cast<uint32_t>(clip.words.size());
  for (std::size_t col = 0; col < columns; ++col) {
    float lo = t.values[col], hi = t.values[col];
    for (std::size_t k = 0; k < keys; ++k) {
      lo = std::min(lo, t.values[k * columns + col]);
      hi = std::max(hi, t.values[k * columns + col]);
    }
    clip.floats.push_back(lo);
    clip.floats.push_back((hi - lo) / detail::kQuantSteps);
  }
  for (std::size_t k = 0; k < keys; ++k) {
    for (std::size_t col = 0; col < columns; ++col) {
      const float* range = &clip.floats[out.floats + 2 * col];
      clip.words.push_back(detail::QuantizeRange(t.values[k * columns + col], range[0], range[1]));
    }
  }
}

// Smallest-three, each of the three stored slots quantized against its range over the
// track (at most [-1/sqrt2, 1/sqrt2]): a joint that turns little keeps finer steps.
void StoreSmallestThree(const RawTrack& t, CompactClip& clip, CompactTrack& out) {
  out.format = TrackFormat::kSmallestThree16;
  out.floats = static_cast<uint32_t>(clip.floats.size());
  out.words = static_cast<uint32_t>(clip.words.size());
  out.largest = static_cast<uint32_t>(4 * clip.largest.size());
  const std::size_t keys = t.times.size();
  std::vector<float> slots(3 * keys);
  for (std::size_t k = 0; k < keys; ++k) {
    const int largest = detail::SmallestThree(&t.values[4 * k], &slots[3 * k]);
    if (k % 4 == 0) clip.largest.push_back(0);
    clip.largest.back() |= static_cast<uint8_t>(largest << (2 * (k % 4)));
  }
  for (std::size_t slot = 0; slot < 3; ++slot) {
    float lo = slots[slot], hi = slots[slot];
    for (std::size_t k = 0; k < keys; ++k) {
      lo = std::min(lo, slots[3 * k + slot]);
      hi = std::max(hi, slots[3 * k + slot]);
    }
    clip.floats.push_back(lo);
    clip.floats.push_back((hi - lo) / detail::kQuantSteps);
  }
  for (std::size_t k = 0; k < keys; ++k) {
    for (std::size_t slot = 0; slot < 3; ++slot) {
      const float* range = &clip.floats[out.floats + 2 * slot];
      clip.words.push_back(detail::QuantizeRange(slots[3 * k + slot], range[0], range[1]));
    }
  }
}

// A LINEAR or STEP joint track with fewer than 16 bits a component: its ranges, its codes
// bit-packed from a byte of its own, rotations' largest indices as kSmallestThree16's.
void StorePacked(const RawTrack& t, uint32_t bits, CompactClip& clip, CompactTrack& out) {
  const detail::QuantizedTrack q = detail::QuantizeTrack(t, bits);
  const bool rotation = t.path == TrackPath::kRotation;
  out.format = rotation ? TrackFormat::kSmallestThreePacked : TrackFormat::kRangePacked;
  out.bits = static_cast<uint8_t>(bits);
  out.floats = static_cast<uint32_t>(clip.floats.size());
  clip.floats.insert(clip.floats.end(), q.ranges.begin(), q.ranges.end());
  out.words = static_cast<uint32_t>(clip.packed.size());
  clip.packed.resize(clip.packed.size() + (q.codes.size() * bits + 7) / 8, 0);
  for (std::size_t i = 0; i < q.codes.size(); ++i)
    detail::WriteBits(&clip.packed[out.words], i * bits, bits, q.codes[i]);
  if (!rotation) return;
  out.largest = static_cast<uint32_t>(4 * clip.largest.size());
  for (std::size_t k = 0; k < q.largest.size(); ++k) {
    if (k % 4 == 0) clip.largest.push_back(0);
    clip.largest.back() |= static_cast<uint8_t>(q.largest[k] << (2 * (k % 4)));
  }
}

// Key times: every animated track's times, once. A track keyed at all of them stores none.
Status StoreTimes(const RawClip& raw, const std::vector<bool>& constant, CompactClip& clip) {
  for (std::size_t i = 0; i < raw.tracks.size(); ++i) {
    if (!constant[i])
      clip.times.insert(clip.times.end(), raw.tracks[i].times.begin(), raw.tracks[i].times.end());
  }
  std::sort(clip.times.begin(), clip.times.end());
  clip.times.erase(std::unique(clip.times.begin(), clip.times.end()), clip.times.end());
  if (clip.times.size() > kMaxClipKeyTimes) {
    return InvalidArgument(fmt::format("clip has {} distinct key times; at most {} are supported",
                                       clip.times.size(), kMaxClipKeyTimes));
  }
  return Status::Ok();
}

void StoreKeyTimes(const RawTrack& t, CompactClip& clip, CompactTrack& out) {
  out.key_count = static_cast<uint32_t>(t.times.size());
  if (t.times == clip.times) return;  // kAllKeyTimes
  out.key_times = static_cast<uint32_t>(clip.key_times.size());
  for (float time : t.times) {
    const auto it = std::lower_bound(clip.times.begin(), clip.times.end(), time);
    clip.key_times.push_back(static_cast<uint16_t>(it - clip.times.begin()));
  }
}

Status ValidateOptions(const ClipBuildOptions& options) {
  const float e = options.max_error_mm;
  if (e == 0 || (e >= kMinMaxErrorMm && e <= kMaxMaxErrorMm)) return Status::Ok();
  return InvalidArgument(
      fmt::format("max_error_mm = {}; must be 0 (the default, {} mm) or within [{}, {}] mm", e,
                  kDefaultMaxErrorMm, kMinMaxErrorMm, kMaxMaxErrorMm));
}

// How each track is stored before bits are chosen (track_bits.h).
Result<std::vector<detail::TrackKind>> ValidateTracks(const RawClip& raw,
                                                      const Skeleton& skeleton) {
  std::vector<detail::TrackKind> kinds(raw.tracks.size());
  for (std::size_t i = 0; i < raw.tracks.size(); ++i) {
    const RawTrack& t = raw.tracks[i];
    if (Status s = ValidateTrack(t, i, skeleton); !s.ok()) return s;
    if (t.times.back() > raw.duration) {
      return InvalidArgument(fmt::format("tracks[{}].times ends at {} s, after clip.duration {} s",
                                         i, t.times.back(), raw.duration));
    }
    if (IsConstant(t)) {
      kinds[i] = IsAtRest(t, skeleton) ? detail::TrackKind::kAtRest : detail::TrackKind::kConstant;
    } else if (t.path != TrackPath::kWeights && t.interpolation != Interpolation::kCubicSpline) {
      kinds[i] = detail::TrackKind::kCandidate;
    } else {
      kinds[i] = detail::TrackKind::kRange16;
    }
  }
  return kinds;
}

void StoreTrack(const RawTrack& t, detail::TrackKind kind, uint32_t bits, CompactClip& clip) {
  CompactTrack out;
  out.path = t.path;
  out.interpolation = t.interpolation;
  out.width = static_cast<uint16_t>(t.width);
  if (t.path == TrackPath::kWeights) {
    out.weight_offset = clip.weight_count;
    clip.weight_count += t.width;
    clip.weight_groups.push_back(t.target);
  } else {
    out.joint = static_cast<uint16_t>(t.target);
  }
  if (kind == detail::TrackKind::kConstant) {
    StoreConstant(t, clip, out);
  } else {
    StoreKeyTimes(t, clip, out);
    if (bits < 16) {
      StorePacked(t, bits, clip, out);
    } else if (t.path == TrackPath::kRotation && t.interpolation != Interpolation::kCubicSpline) {
      StoreSmallestThree(t, clip, out);
    } else {
      StoreRange16(t, clip, out);
    }
  }
  clip.tracks.push_back(out);
}

}  // namespace

Result<CompactClip> BuildCompactClip(const RawClip& raw, const Skeleton& skeleton,
                                     const ClipBuildOptions& options) {
  if (Status s = ValidateSkeleton(skeleton); !s.ok()) return s;
  if (Status s = ValidateOptions(options); !s.ok()) return s;
  if (!std::isfinite(raw.duration) || raw.duration < 0) {
    return InvalidArgument(
        fmt::format("clip.duration = {}; must be finite and >= 0", raw.duration));
  }
  Result<std::vector<detail::TrackKind>> kinds = ValidateTracks(raw, skeleton);
  if (!kinds.ok()) return kinds.status();
  std::vector<bool> constant(raw.tracks.size());
  for (std::size_t i = 0; i < raw.tracks.size(); ++i)
    constant[i] =
        (*kinds)[i] == detail::TrackKind::kAtRest || (*kinds)[i] == detail::TrackKind::kConstant;
  CompactClip clip;
  clip.name = raw.name;
  clip.duration = raw.duration;
  clip.joint_count = skeleton.joint_count();
  clip.max_error_mm = options.max_error_mm == 0 ? kDefaultMaxErrorMm : options.max_error_mm;
  if (Status s = StoreTimes(raw, constant, clip); !s.ok()) return s;
  const std::vector<uint32_t> bits =
      detail::ChooseTrackBits(raw, skeleton, *kinds, clip.max_error_mm);
  for (std::size_t i = 0; i < raw.tracks.size(); ++i) {
    if ((*kinds)[i] != detail::TrackKind::kAtRest)
      StoreTrack(raw.tracks[i], (*kinds)[i], bits[i], clip);
  }
  // The sampler reads a packed key's components 8 bytes at a time (quantize.h's ReadKey3).
  if (!clip.packed.empty()) clip.packed.resize(clip.packed.size() + kPackedSlack, 0);
  clip.id = ClipId(clip.Serialize());
  clip.plan = std::make_shared<const SamplingPlan>(MakeSamplingPlan(clip));
  return clip;
}

}  // namespace skinserve::animation
