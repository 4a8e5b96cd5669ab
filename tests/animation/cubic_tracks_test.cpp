// CUBICSPLINE tracks keyed at every clip time, which the sampler takes from its plan
// (SamplingPlan::cubics, 3-wide translations and scales and 4-wide rotations), against a
// float64 Hermite of the same keys (glTF's: value, out-tangent of key k, value, in-tangent
// of key k + 1, tangents per second). In- and out-tangents differ, so a sampler that took
// one for the other fails. The bound: each stored component's quantization error (a
// track's range / 131070) times its Hermite weight, plus float rounding.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "sampling_plan.h"
#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/sampling_job.h"

namespace skinserve::animation {
namespace {

const std::vector<float> kTimes = {0.0f, 0.4f, 1.0f, 1.5f, 2.25f};

// Per key: in-tangent, value, out-tangent, `width` floats each, all different.
RawTrack CubicTrack(TrackPath path, uint32_t joint, uint32_t width, double phase) {
  RawTrack t{path, Interpolation::kCubicSpline, joint, width, kTimes, {}};
  for (std::size_t k = 0; k < kTimes.size(); ++k) {
    for (int part = 0; part < 3; ++part) {
      for (uint32_t c = 0; c < width; ++c) {
        const double x = phase + 1.7 * static_cast<double>(k) + 0.9 * part + 0.37 * c;
        const double base = path == TrackPath::kScale ? 1.0 : 0.0;
        t.values.push_back(
            static_cast<float>(part == 1 ? base + 0.8 * std::sin(x) : 2.5 * std::cos(1.3 * x)));
      }
    }
  }
  return t;
}

struct Expected {
  std::vector<double> value;  // `width` components (a rotation: normalised)
  std::vector<double> bound;  // per component
};

// The float64 Hermite of `track` at t (clamped to its keys), and how far the stored clip
// may be from it.
Expected Hermite(const RawTrack& track, double t) {
  const std::size_t w = track.width, n = track.times.size();
  auto at = [&](std::size_t k, int part, std::size_t c) {
    return double{track.values[(3 * k + static_cast<std::size_t>(part)) * w + c]};
  };
  auto error = [&](int part, std::size_t c) {  // the quantization step's half
    double lo = at(0, part, c), hi = lo;
    for (std::size_t k = 1; k < n; ++k) {
      lo = std::min(lo, at(k, part, c));
      hi = std::max(hi, at(k, part, c));
    }
    return (hi - lo) / 131070.0;
  };
  std::size_t k = 0;
  while (k + 1 < n && track.times[k + 1] <= t) ++k;
  Expected e{std::vector<double>(w), std::vector<double>(w)};
  double h00 = 1, h10 = 0, h01 = 0, h11 = 0, dt = 0;
  if (k + 1 < n && t > track.times[0]) {
    dt = double{track.times[k + 1]} - track.times[k];
    const double u = (t - track.times[k]) / dt, u2 = u * u, u3 = u2 * u;
    h00 = 2 * u3 - 3 * u2 + 1, h10 = (u3 - 2 * u2 + u) * dt;
    h01 = -2 * u3 + 3 * u2, h11 = (u3 - u2) * dt;
  } else if (t > track.times[0]) {
    k = n - 1;
  }
  const std::size_t next = std::min(k + 1, n - 1);
  double length = 0;
  for (std::size_t c = 0; c < w; ++c) {
    e.value[c] =
        h00 * at(k, 1, c) + h10 * at(k, 2, c) + h01 * at(next, 1, c) + h11 * at(next, 0, c);
    e.bound[c] = (std::fabs(h00) + std::fabs(h01)) * error(1, c) + std::fabs(h10) * error(2, c) +
                 std::fabs(h11) * error(0, c) + 1e-6 * (1 + std::fabs(e.value[c]));
    length += e.value[c] * e.value[c];
  }
  if (track.path == TrackPath::kRotation) {  // normalising at most doubles the error
    length = std::sqrt(length);
    for (std::size_t c = 0; c < w; ++c) {
      e.value[c] /= length;
      e.bound[c] = 2 * e.bound[c] / length + 1e-6;
    }
  }
  return e;
}

TEST(CubicTracks, PlannedHermiteMatchesFloat64WithDistinctTangents) {
  Skeleton skeleton;
  skeleton.parents = {-1, 0};
  skeleton.rest.resize(2);
  skeleton.palette_joints = {0, 1};
  skeleton.inverse_bind.resize(2);
  RawClip raw{"cubic", kTimes.back(), {}};
  raw.tracks = {
      CubicTrack(TrackPath::kTranslation, 0, 3, 0.0), CubicTrack(TrackPath::kScale, 0, 3, 1.0),
      CubicTrack(TrackPath::kRotation, 1, 4, 2.0), CubicTrack(TrackPath::kTranslation, 1, 3, 3.0)};
  auto clip = BuildCompactClip(raw, skeleton);
  ASSERT_TRUE(clip.ok()) << clip.status().ToString();
  ASSERT_NE(clip->plan, nullptr);
  ASSERT_EQ(clip->plan->cubics.size(), raw.tracks.size()) << "every track on the planned path";

  std::vector<Transform> pose(2);
  SamplingContext context;
  for (int step = -2; step <= 240; ++step) {
    const double t = step / 100.0;  // before, on, between keys and after the last
    for (SamplingContext* c : {static_cast<SamplingContext*>(nullptr), &context}) {
      const SamplingJob job{
          &skeleton, clip.operator->(), static_cast<float>(t), TimeMode::kClamp, pose, {}, c};
      ASSERT_TRUE(job.Run().ok());
      for (const RawTrack& track : raw.tracks) {
        const Transform& got = pose[track.target];
        const float* v = track.path == TrackPath::kTranslation
                             ? got.translation
                             : (track.path == TrackPath::kScale ? got.scale : got.rotation);
        const Expected want = Hermite(track, std::clamp(t, 0.0, double{kTimes.back()}));
        for (std::size_t i = 0; i < track.width; ++i) {
          EXPECT_NEAR(v[i], want.value[i], want.bound[i])
              << "t " << t << " joint " << track.target << " path " << static_cast<int>(track.path)
              << " component " << i;
        }
      }
      if (::testing::Test::HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace skinserve::animation
