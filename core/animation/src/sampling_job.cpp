#include "skinserve/animation/sampling_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "float4.h"
#include "quantize.h"
#include "quaternion.h"
#include "sample_rotations4.h"
#include "sampling_plan.h"

namespace skinserve::animation {
namespace {

// Where a track's keys bracket the sample: key k, the next, and how far between (u).
struct Segment {
  uint32_t k = 0;
  uint32_t next = 0;
  float u = 0;
  float seconds = 0;  // the interval's length (CUBICSPLINE tangents are per second)
};

// Where the clip's key times bracket t: the segment every track keyed at all of them
// shares (most tracks), so it is found once a sample. `hint`: the segment of the last call
// (time moving forward is in it or the next: no search), checked, so any hint is safe.
Segment FindClipSegment(const CompactClip& clip, float t, uint32_t hint) {
  Segment s;
  const std::vector<float>& times = clip.times;
  const std::size_t n = times.size();
  std::size_t after = 0;  // the first key after t
  if (hint + 1 < n && times[hint] <= t && t < times[hint + 1]) {
    after = hint + 1;
  } else if (hint + 2 < n && times[hint + 1] <= t && t < times[hint + 2]) {
    after = hint + 2;
  } else {
    after =
        static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t) - times.begin());
  }
  if (after == 0 || after == n) {
    s.k = s.next = after == 0 ? 0 : static_cast<uint32_t>(n) - 1;
    return s;
  }
  s.k = static_cast<uint32_t>(after) - 1;
  s.next = s.k + 1;
  s.seconds = times[s.next] - times[s.k];
  s.u = std::clamp((t - times[s.k]) / s.seconds, 0.0f, 1.0f);
  return s;
}

// A track keyed at some of the clip's times: its own last key at or before the clip's
// segment start (`global`), and the next.
Segment FindTrackSegment(const CompactClip& clip, const CompactTrack& track, const Segment& global,
                         float t) {
  Segment s;
  const uint32_t last = track.key_count - 1;
  const uint16_t* keys = &clip.key_times[track.key_times];
  const uint16_t* after = std::upper_bound(keys, keys + track.key_count, global.k);
  s.k = after == keys ? 0 : static_cast<uint32_t>(after - keys) - 1;
  if (s.k >= last || t <= clip.times[keys[0]]) {  // before the first key or at/after the last
    s.k = s.next = t <= clip.times[keys[0]] ? 0 : last;
    return s;
  }
  s.next = s.k + 1;
  const float t0 = clip.times[keys[s.k]];
  s.seconds = clip.times[keys[s.next]] - t0;
  s.u = std::clamp((t - t0) / s.seconds, 0.0f, 1.0f);
  return s;
}

// Component `col` of key `k` of a kRange16 or packed track whose keys hold `columns`
// components (a smallest-three track's: 3).
float Range16(const CompactClip& clip, const CompactTrack& track, uint32_t k, uint32_t columns,
              uint32_t col) {
  const float* range = &clip.floats[track.floats + 2 * col];
  if (track.format == TrackFormat::kRangePacked ||
      track.format == TrackFormat::kSmallestThreePacked) {
    const uint64_t at = (uint64_t{k} * columns + col) * track.bits;
    return detail::DequantizeCode(
        detail::ReadBits(clip.packed.data() + track.words, at, track.bits), range[0], range[1]);
  }
  return detail::DequantizeRange(clip.words[track.words + k * columns + col], range[0], range[1]);
}

void SmallestThree(const CompactClip& clip, const CompactTrack& track, uint32_t k, float q[4]) {
  const uint32_t slot = track.largest + k;
  const int largest = (clip.largest[slot / 4] >> (2 * (slot % 4))) & 3;
  float small[3];
  for (uint32_t c = 0; c < 3; ++c) small[c] = Range16(clip, track, k, 3, c);
  detail::FromSmallestThree(small, largest, q);
}

// A track's value at the segment into out[0..width).
void SampleTrack(const CompactClip& clip, const CompactTrack& track, const Segment& s, float* out) {
  const uint32_t w = track.width;
  if (track.format == TrackFormat::kConstant) {
    const float* v = &clip.floats[track.floats];
    for (uint32_t c = 0; c < w; ++c) out[c] = v[c];
    return;
  }
  if (track.format == TrackFormat::kSmallestThree16 ||
      track.format == TrackFormat::kSmallestThreePacked) {
    float a[4];
    SmallestThree(clip, track, s.k, a);
    if (track.interpolation == Interpolation::kStep || s.next == s.k) {
      std::copy_n(a, 4, out);
      return;
    }
    float b[4];
    SmallestThree(clip, track, s.next, b);
    detail::Slerp(a, b, s.u, out);
    return;
  }
  const bool cubic = track.interpolation == Interpolation::kCubicSpline;
  const uint32_t columns = cubic ? 3 * w : w, value = cubic ? w : 0;
  if (track.interpolation == Interpolation::kStep || s.next == s.k) {
    for (uint32_t c = 0; c < w; ++c) out[c] = Range16(clip, track, s.k, columns, value + c);
  } else if (!cubic) {
    for (uint32_t c = 0; c < w; ++c) {
      const float a = Range16(clip, track, s.k, columns, c);
      out[c] = a + s.u * (Range16(clip, track, s.next, columns, c) - a);
    }
  } else {  // Hermite: value, out-tangent of k; value, in-tangent of next
    const float u = s.u, u2 = u * u, u3 = u2 * u;
    const float h00 = 2 * u3 - 3 * u2 + 1, h10 = (u3 - 2 * u2 + u) * s.seconds;
    const float h01 = -2 * u3 + 3 * u2, h11 = (u3 - u2) * s.seconds;
    for (uint32_t c = 0; c < w; ++c) {
      out[c] = h00 * Range16(clip, track, s.k, columns, w + c) +
               h10 * Range16(clip, track, s.k, columns, 2 * w + c) +
               h01 * Range16(clip, track, s.next, columns, w + c) +
               h11 * Range16(clip, track, s.next, columns, c);
    }
  }
  if (track.path == TrackPath::kRotation) detail::Normalize4(out);
}

float* Target(const CompactTrack& track, Transform& t) {
  switch (track.path) {
    case TrackPath::kTranslation:
      return t.translation;
    case TrackPath::kRotation:
      return t.rotation;
    default:
      return t.scale;
  }
}

void SampleConstants(const SamplingPlan& plan, std::span<Transform> output) {
  static_assert(sizeof(Transform) == 10 * sizeof(float));
  for (const SamplingPlan::Constant& c : plan.constants) {
    Transform& t = output[c.joint];  // element by element: no memmove call
    float* f = c.offset == 0 ? t.translation : (c.offset == 3 ? t.rotation : t.scale);
    f[0] = c.value[0];
    f[1] = c.value[1];
    f[2] = c.value[2];
    if (c.offset == 3) f[3] = c.value[3];  // a rotation
  }
}

// LINEAR 16-bit or packed translations and scales keyed at every clip time: as SampleTrack
// does them.
SKINSERVE_ALWAYS_INLINE void SampleVectors(const CompactClip& clip, const SamplingPlan& plan,
                                           const Segment& s, std::span<Transform> output) {
  for (const SamplingPlan::Vector& v : plan.vectors) {
    Transform& t = output[v.joint];
    float* out =
        static_cast<TrackPath>(v.path) == TrackPath::kTranslation ? t.translation : t.scale;
    if (v.packed == 0) {
      const uint16_t* a = &clip.words[v.bytes / 2 + 3 * s.k];
      const uint16_t* b = &clip.words[v.bytes / 2 + 3 * s.next];
      for (int c = 0; c < 3; ++c) {
        const float va = detail::DequantizeRange(a[c], v.min[c], v.step[c]);
        out[c] = va + s.u * (detail::DequantizeRange(b[c], v.min[c], v.step[c]) - va);
      }
      continue;
    }
    uint32_t a[3], b[3];
    detail::ReadKey3(clip.packed.data() + v.bytes, s.k, v.bits, a);
    detail::ReadKey3(clip.packed.data() + v.bytes, s.next, v.bits, b);
    for (int c = 0; c < 3; ++c) {
      const float va = detail::DequantizeCode(a[c], v.min[c], v.step[c]);
      out[c] = va + s.u * (detail::DequantizeCode(b[c], v.min[c], v.step[c]) - va);
    }
  }
}

// Component by component as DequantizeRange: min + step * q, 4 lanes (past `width`: 0).
// A 3-wide key part is read from the u16 before it, which is in the track: SampleCubics
// reads a key's in-tangent (its first u16) only for key k + 1.
SKINSERVE_ALWAYS_INLINE detail::F4 Dequantize4(const uint16_t* q, uint32_t width, const float* min,
                                               const float* step) {
  const detail::F4 v = width == 4 ? detail::LoadU16x4(q) : detail::LoadU16x3(q);
  return detail::Load4(min) + detail::Load4(step) * v;
}

// CUBICSPLINE tracks keyed at every clip time: SampleTrack's Hermite, a track's components
// side by side.
SKINSERVE_ALWAYS_INLINE void SampleCubics(const CompactClip& clip, const SamplingPlan& plan,
                                          const Segment& s, std::span<Transform> output) {
  using detail::F4;
  const float u = s.u, u2 = u * u, u3 = u2 * u;
  const F4 h00 = detail::Splat(2 * u3 - 3 * u2 + 1),
           h10 = detail::Splat((u3 - 2 * u2 + u) * s.seconds);
  const F4 h01 = detail::Splat(-2 * u3 + 3 * u2), h11 = detail::Splat((u3 - u2) * s.seconds);
  for (const SamplingPlan::Cubic& c : plan.cubics) {
    const uint32_t w = c.width;
    const uint16_t* a = &clip.words[c.words + 3 * w * s.k];
    F4 v = Dequantize4(a + w, w, c.min[1], c.step[1]);  // key k's value
    if (s.next != s.k) {
      const uint16_t* b = &clip.words[c.words + 3 * w * s.next];
      v = h00 * v + h10 * Dequantize4(a + 2 * w, w, c.min[2], c.step[2]) +
          h01 * Dequantize4(b + w, w, c.min[1], c.step[1]) +
          h11 * Dequantize4(b, w, c.min[0], c.step[0]);
    }
    alignas(16) float value[4];
    detail::Store4(v, value);
    Transform& t = output[c.joint];
    const TrackPath path = static_cast<TrackPath>(c.path);
    if (path == TrackPath::kRotation) {
      detail::Normalize4(value);
      std::copy_n(value, 4, t.rotation);
    } else {
      std::copy_n(value, 3, path == TrackPath::kTranslation ? t.translation : t.scale);
    }
  }
}

// The plan's 16-bit LINEAR vectors and CUBICSPLINE tracks, compiled for each ISA (isa_clones.h).
void SampleVectorsAndCubicsBaseline(const CompactClip& clip, const SamplingPlan& plan,
                                    const Segment& s, std::span<Transform> output) {
  SampleVectors(clip, plan, s, output);
  SampleCubics(clip, plan, s, output);
}

#if SKINSERVE_HAS_AVX2_FMA_CLONES
SKINSERVE_AVX2_FMA void SampleVectorsAndCubicsAvx2Fma(const CompactClip& clip,
                                                      const SamplingPlan& plan, const Segment& s,
                                                      std::span<Transform> output) {
  SampleVectors(clip, plan, s, output);
  SampleCubics(clip, plan, s, output);
}
#endif

void SampleVectorsAndCubics(const CompactClip& clip, const SamplingPlan& plan, const Segment& s,
                            std::span<Transform> output) {
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  if (detail::RunAvx2Fma()) return SampleVectorsAndCubicsAvx2Fma(clip, plan, s, output);
#endif
  SampleVectorsAndCubicsBaseline(clip, plan, s, output);
}

void SampleOne(const CompactClip& clip, const CompactTrack& track, const Segment& global, float t,
               std::span<Transform> output, std::span<float> morph_weights) {
  float* out = track.path == TrackPath::kWeights ? &morph_weights[track.weight_offset]
                                                 : Target(track, output[track.joint]);
  if (track.format == TrackFormat::kConstant || track.key_times == kAllKeyTimes) {
    SampleTrack(clip, track, global, out);
  } else {
    SampleTrack(clip, track, FindTrackSegment(clip, track, global, t), out);
  }
}

// Where the rotation keys of the segment come from: the context's cache as it stands,
// shifted by one segment, or decoded afresh (and then kept there).
detail::RotationKeys CachedKeys(const CompactClip& clip, const Segment& s,
                                SamplingContext* context) {
  if (context == nullptr) return {};
  detail::RotationKeys keys;
  if (context->plan != clip.plan) {
    context->plan = clip.plan;
    context->valid = false;
    context->keys.resize(32 * clip.plan->rotations.size());
  }
  keys.cache = context->keys.data();
  if (!context->valid) {
    keys.state = detail::RotationKeys::kDecode;
  } else if (s.k == context->k && s.next == context->next) {
    keys.state = detail::RotationKeys::kCached;
  } else if (s.k == context->next && s.next == s.k + 1) {
    keys.state = detail::RotationKeys::kShift;
  } else {
    keys.state = detail::RotationKeys::kDecode;
  }
  context->k = s.k;
  context->next = s.next;
  context->valid = true;
  return keys;
}

// The time a clip is sampled at: looped into [0, duration) or clamped to [0, duration].
float ClipTime(const CompactClip& clip, float time, TimeMode mode) {
  if (mode == TimeMode::kLoop && clip.duration > 0) {
    const float t = std::fmod(time, clip.duration);
    return t < 0 ? t + clip.duration : t;
  }
  return std::clamp(time, 0.0f, clip.duration);
}

}  // namespace

void SamplingContext::Reset() {
  plan.reset();
  valid = false;
  keys.clear();
}

Status SamplingJob::Validate() const {
  if (skeleton == nullptr) return InvalidArgument("sampling: skeleton is missing");
  if (clip == nullptr) return InvalidArgument("sampling: clip is missing");
  if (clip->joint_count != skeleton->joint_count()) {
    return InvalidArgument(
        fmt::format("sampling: clip {} was built for a skeleton of {} joints; this one has {}",
                    clip->id, clip->joint_count, skeleton->joint_count()));
  }
  if (!std::isfinite(time)) {
    return InvalidArgument(fmt::format("sampling: time is {}; it must be finite seconds", time));
  }
  if (output.size() != skeleton->joint_count()) {
    return InvalidArgument(
        fmt::format("sampling: output has {} transforms; the skeleton has {} joints", output.size(),
                    skeleton->joint_count()));
  }
  if (morph_weights.size() != clip->weight_count) {
    return InvalidArgument(fmt::format("sampling: morph_weights has {} floats; clip {} samples {}",
                                       morph_weights.size(), clip->id, clip->weight_count));
  }
  return Status::Ok();
}

Status SamplingJob::Run() const {
  if (Status s = Validate(); !s.ok()) return s;
  const float t = ClipTime(*clip, time, mode);
  if (clip->plan == nullptr) {  // a clip not made by BuildCompactClip: one track at a time
    const Segment global = FindClipSegment(*clip, t, 0);
    std::copy(skeleton->rest.begin(), skeleton->rest.end(), output.begin());
    for (const CompactTrack& track : clip->tracks) {
      SampleOne(*clip, track, global, t, output, morph_weights);
    }
    return Status::Ok();
  }
  const SamplingPlan& plan = *clip->plan;
  const bool same_clip = context != nullptr && context->plan == clip->plan;
  const Segment global = FindClipSegment(*clip, t, same_clip && context->valid ? context->k : 0);
  for (const SamplingPlan::JointRun& run : plan.rest_runs) {
    std::copy_n(&skeleton->rest[run.first], run.count, &output[run.first]);
  }
  SampleConstants(plan, output);
  detail::SampleRotations4(*clip, plan.rotations, global.k, global.next, global.u, output,
                           CachedKeys(*clip, global, context));
  detail::SampleRotations4(*clip, plan.step_rotations, global.k, global.k, 0, output, {});
  SampleVectorsAndCubics(*clip, plan, global, output);
  for (uint32_t i : plan.others)
    SampleOne(*clip, clip->tracks[i], global, t, output, morph_weights);
  return Status::Ok();
}

Status MorphSamplingJob::Run() const {
  if (clip == nullptr) return InvalidArgument("morph sampling: clip is missing");
  if (!std::isfinite(time)) {
    return InvalidArgument(
        fmt::format("morph sampling: time is {}; it must be finite seconds", time));
  }
  if (morph_weights.size() != clip->weight_count) {
    return InvalidArgument(
        fmt::format("morph sampling: morph_weights has {} floats; clip {} samples {}",
                    morph_weights.size(), clip->id, clip->weight_count));
  }
  const float t = ClipTime(*clip, time, mode);
  const Segment global = FindClipSegment(*clip, t, 0);
  for (const CompactTrack& track : clip->tracks) {
    if (track.path == TrackPath::kWeights) SampleOne(*clip, track, global, t, {}, morph_weights);
  }
  return Status::Ok();
}

}  // namespace skinserve::animation
