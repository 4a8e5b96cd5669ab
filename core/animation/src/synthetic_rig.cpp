#include "skinserve/animation/synthetic_rig.h"

#include <array>
#include <cmath>
#include <numbers>
#include <random>

namespace skinserve::animation {
namespace {

using Quat = std::array<double, 4>;  // x y z w

Quat Mul(const Quat& a, const Quat& b) {
  return {a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1],
          a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
          a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3],
          a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]};
}

Quat AxisAngle(const std::array<double, 3>& axis, double angle) {
  const double s = std::sin(angle / 2);
  return {axis[0] * s, axis[1] * s, axis[2] * s, std::cos(angle / 2)};
}

// Row-major 3x4 of T * R (scale 1), in double, and its rigid inverse.
using Mat = std::array<double, 12>;
Mat Compose(const double t[3], const Quat& q) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),     t[0],
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),     t[1],
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y), t[2]};
}
Mat Multiply(const Mat& a, const Mat& b) {
  Mat o{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      o[4 * r + c] = a[4 * r] * b[c] + a[4 * r + 1] * b[4 + c] + a[4 * r + 2] * b[8 + c];
    }
    o[4 * r + 3] += a[4 * r + 3];
  }
  return o;
}
Mat RigidInverse(const Mat& m) {
  Mat o{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) o[4 * r + c] = m[4 * c + r];
    o[4 * r + 3] = -(o[4 * r] * m[3] + o[4 * r + 1] * m[7] + o[4 * r + 2] * m[11]);
  }
  return o;
}

struct Swing {
  std::array<double, 3> axis;
  double amplitude, frequency, phase;
  Quat At(const Quat& rest, double t) const {
    return Mul(rest,
               AxisAngle(axis, amplitude * std::sin(2 * std::numbers::pi * frequency * t + phase)));
  }
};

void AddKeys(RawTrack& track, double time, const float* v) {
  track.times.push_back(static_cast<float>(time));
  track.values.insert(track.values.end(), v, v + track.width);
}

// A rotation track of one joint: the swing sampled at the keys (CUBICSPLINE: with its
// derivative as tangents, by central differences in double).
RawTrack RotationTrack(uint32_t joint, Interpolation interp, const Quat& rest, const Swing& swing,
                       uint32_t keys, double dt) {
  RawTrack track{TrackPath::kRotation, interp, joint, 4, {}, {}};
  for (uint32_t k = 0; k < keys; ++k) {
    const double t = k * dt;
    const Quat q = swing.At(rest, t);
    float value[4], in[4];
    for (int c = 0; c < 4; ++c) value[c] = static_cast<float>(q[c]);
    if (interp != Interpolation::kCubicSpline) {
      AddKeys(track, t, value);
      continue;
    }
    constexpr double h = 1e-5;
    const Quat a = swing.At(rest, t - h), b = swing.At(rest, t + h);
    for (int c = 0; c < 4; ++c) in[c] = static_cast<float>((b[c] - a[c]) / (2 * h));
    track.times.push_back(static_cast<float>(t));
    track.values.insert(track.values.end(), in, in + 4);
    track.values.insert(track.values.end(), value, value + 4);
    track.values.insert(track.values.end(), in, in + 4);
  }
  return track;
}

// Translation: constant (the bone), except the root walking forward.
RawTrack TranslationTrack(uint32_t j, const Transform& rest, uint32_t keys, double dt) {
  RawTrack translation{TrackPath::kTranslation, Interpolation::kLinear, j, 3, {}, {}};
  for (uint32_t k = 0; k < keys; ++k) {
    const double time = k * dt;
    float v[3] = {rest.translation[0], rest.translation[1], rest.translation[2]};
    if (j == 0) {
      v[0] = static_cast<float>(0.05 * std::sin(2 * std::numbers::pi * time));
      v[1] = static_cast<float>(1.0 + 0.03 * std::sin(4 * std::numbers::pi * time));
      v[2] = static_cast<float>(0.7 * time);
    }
    AddKeys(translation, time, v);
  }
  return translation;
}

// Scale: 1, except one joint (`pulsing`) pulsing by 10%.
RawTrack ScaleTrack(uint32_t j, bool pulsing, uint32_t keys, double dt) {
  RawTrack scale{TrackPath::kScale, Interpolation::kLinear, j, 3, {}, {}};
  for (uint32_t k = 0; k < keys; ++k) {
    const float p = pulsing ? static_cast<float>(1.0 + 0.1 * std::sin(3.0 * k * dt)) : 1.0f;
    const float v[3] = {p, p, p};
    AddKeys(scale, k * dt, v);
  }
  return scale;
}

// Four morph weights, each a phase-shifted sine in [0, 1].
RawTrack WeightsTrack(uint32_t keys, double dt) {
  RawTrack weights{TrackPath::kWeights, Interpolation::kLinear, 0, 4, {}, {}};
  for (uint32_t k = 0; k < keys; ++k) {
    float v[4];
    for (int c = 0; c < 4; ++c) v[c] = static_cast<float>(0.5 + 0.5 * std::sin(2.0 * k * dt + c));
    AddKeys(weights, k * dt, v);
  }
  return weights;
}

}  // namespace

SyntheticRig MakeSyntheticRig(uint32_t joints, uint32_t seed, float seconds,
                              float keys_per_second) {
  std::mt19937 rng(seed);
  auto uniform = [&](double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(rng()) / 4294967296.0);
  };
  auto unit = [&] {
    std::array<double, 3> v{uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)};
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 1e-9;
    return std::array<double, 3>{v[0] / l, v[1] / l, v[2] / l};
  };
  SyntheticRig rig;
  Skeleton& s = rig.skeleton;
  const uint32_t keys = static_cast<uint32_t>(std::lround(seconds * keys_per_second)) + 1;
  const double dt = 1.0 / keys_per_second;
  rig.clip.name = "synthetic";
  rig.clip.duration = static_cast<float>((keys - 1) * dt);
  std::vector<Mat> model(joints);
  for (uint32_t j = 0; j < joints; ++j) {
    // Mostly chains (limbs, spine), sometimes a branch off a recent joint.
    const int parent =
        j == 0 ? -1
               : (uniform(0, 1) < 0.7 ? static_cast<int>(j) - 1
                                      : static_cast<int>(uniform(std::max(0.0, j - 8.0), j)));
    const std::array<double, 3> dir = unit();
    const double length = j == 0 ? 1.0 : uniform(0.05, 0.25);
    const double t[3] = {dir[0] * length, j == 0 ? 1.0 : dir[1] * length,
                         j == 0 ? 0.0 : dir[2] * length};
    const Quat rest = AxisAngle(unit(), uniform(-0.5, 0.5));
    Transform rest_t;
    for (int c = 0; c < 3; ++c) rest_t.translation[c] = static_cast<float>(t[c]);
    for (int c = 0; c < 4; ++c) rest_t.rotation[c] = static_cast<float>(rest[c]);
    s.parents.push_back(static_cast<int16_t>(parent));
    s.rest.push_back(rest_t);
    s.names.push_back("joint" + std::to_string(j));
    const double rest_f[3] = {rest_t.translation[0], rest_t.translation[1], rest_t.translation[2]};
    const Mat local = Compose(rest_f, rest);
    model[j] = parent < 0 ? local : Multiply(model[static_cast<std::size_t>(parent)], local);
    s.palette_joints.push_back(static_cast<uint16_t>(j));
    Affine ibm;
    const Mat inverse = RigidInverse(model[j]);
    for (int e = 0; e < 12; ++e)
      ibm.m[e] = static_cast<float>(inverse[static_cast<std::size_t>(e)]);
    s.inverse_bind.push_back(ibm);

    rig.clip.tracks.push_back(TranslationTrack(j, rest_t, keys, dt));
    const Swing swing{unit(), uniform(0.1, 0.8), uniform(0.5, 1.5), uniform(0, 6.28)};
    const Interpolation interp =
        j % 7 == 3 ? Interpolation::kCubicSpline
                   : (j % 11 == 5 ? Interpolation::kStep : Interpolation::kLinear);
    rig.clip.tracks.push_back(RotationTrack(j, interp, rest, swing, keys, dt));
    rig.clip.tracks.push_back(ScaleTrack(j, j == joints / 2, keys, dt));
  }
  rig.clip.tracks.push_back(WeightsTrack(keys, dt));
  return rig;
}

}  // namespace skinserve::animation
