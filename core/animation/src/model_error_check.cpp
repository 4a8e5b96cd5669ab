#include "model_error_check.h"

#include <algorithm>
#include <cmath>

#include "skinserve/animation/compact_clip.h"

namespace skinserve::animation::detail {
namespace {

// glTF's slerp in double, the shorter way round.
void SlerpD(const double* a, const double* b, double u, double* out) {
  double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  const double sign = dot < 0 ? -1.0 : 1.0;
  dot = std::min(1.0, dot * sign);
  const double theta = std::acos(dot);
  double wa = 1 - u, wb = u;
  if (theta > 1e-9) {
    wa = std::sin((1 - u) * theta) / std::sin(theta);
    wb = std::sin(u * theta) / std::sin(theta);
  }
  for (int c = 0; c < 4; ++c) out[c] = wa * a[c] + wb * sign * b[c];
}

void NormalizeD(double* q) {
  const double l = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (int c = 0; c < 4; ++c) q[c] /= l;
}

// The track's value at t (seconds), clamped to its first and last keys, in double.
void SampleD(const StoredJointTrack& tr, double t, double* out) {
  const std::vector<float>& times = *tr.times;
  const uint32_t w = tr.path == TrackPath::kRotation ? 4 : 3;
  const bool cubic = tr.interpolation == Interpolation::kCubicSpline;
  const std::size_t stride = cubic ? 3 * w : w, value = cubic ? w : 0;
  const std::size_t n = tr.values.size() / stride;
  const std::size_t after = static_cast<std::size_t>(
      std::upper_bound(times.begin(), times.begin() + static_cast<std::ptrdiff_t>(n), t,
                       [](double x, float y) { return x < double{y}; }) -
      times.begin());
  auto at = [&](std::size_t k, std::size_t part, uint32_t c) {
    return double{tr.values[k * stride + part + c]};
  };
  if (after == 0 || after == n || tr.interpolation == Interpolation::kStep) {
    const std::size_t k = after == 0 ? 0 : after - 1;
    for (uint32_t c = 0; c < w; ++c) out[c] = at(k, value, c);
  } else {
    const std::size_t k = after - 1;
    const double dt = double{times[k + 1]} - times[k], u = (t - times[k]) / dt;
    if (cubic) {
      const double u2 = u * u, u3 = u2 * u;
      for (uint32_t c = 0; c < w; ++c) {
        out[c] = (2 * u3 - 3 * u2 + 1) * at(k, w, c) + (u3 - 2 * u2 + u) * dt * at(k, 2 * w, c) +
                 (-2 * u3 + 3 * u2) * at(k + 1, w, c) + (u3 - u2) * dt * at(k + 1, 0, c);
      }
    } else if (tr.path == TrackPath::kRotation) {
      double a[4], b[4];
      for (uint32_t c = 0; c < 4; ++c) a[c] = at(k, 0, c), b[c] = at(k + 1, 0, c);
      NormalizeD(a);
      NormalizeD(b);
      SlerpD(a, b, u, out);
    } else {
      for (uint32_t c = 0; c < w; ++c) out[c] = at(k, 0, c) + u * (at(k + 1, 0, c) - at(k, 0, c));
    }
  }
  if (tr.path == TrackPath::kRotation) NormalizeD(out);
}

// M = T * R * S, 3x4 row-major.
void Trs(const double* t, const double* q, const double* s, double* m) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m[4 * row + col] = r[row][col] * s[col];
    m[4 * row + 3] = t[row];
  }
}

void Compose(const double* a, const double* b, double* out) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      out[4 * r + c] = a[4 * r] * b[c] + a[4 * r + 1] * b[4 + c] + a[4 * r + 2] * b[8 + c] +
                       (c == 3 ? a[4 * r + 3] : 0.0);
    }
  }
}

// Every key time of the clip and the times halfway between; with STEP tracks also the float
// just before each key (a STEP track still holds the key before while the others reach it).
std::vector<double> CheckTimes(const RawClip& raw) {
  std::vector<float> keys;
  bool step = false;
  for (const RawTrack& t : raw.tracks) {
    keys.insert(keys.end(), t.times.begin(), t.times.end());
    step = step || t.interpolation == Interpolation::kStep;
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<double> times;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (i > 0) {
      times.push_back(static_cast<float>(0.5 * (double{keys[i - 1]} + keys[i])));
      if (step) times.push_back(std::nextafter(keys[i], 0.0f));
    }
    times.push_back(keys[i]);
  }
  return times;
}

// Per joint: how much its palette entries' inverse binds can stretch a row of its model
// 3x3's error (their largest column length, at least 1): the palette is what skins.
std::vector<double> PaletteStretch(const Skeleton& skeleton) {
  std::vector<double> stretch(skeleton.joint_count(), 1.0);
  for (uint32_t p = 0; p < skeleton.palette_size(); ++p) {
    const float* m = skeleton.inverse_bind[p].m;
    double& s = stretch[skeleton.palette_joints[p]];
    for (int c = 0; c < 3; ++c) {
      s = std::max(s, std::sqrt(double{m[c]} * m[c] + double{m[4 + c]} * m[4 + c] +
                                double{m[8 + c]} * m[8 + c]));
    }
  }
  return stretch;
}

std::vector<StoredJointTrack> OriginalTracks(const RawClip& raw) {
  std::vector<StoredJointTrack> tracks;
  for (const RawTrack& t : raw.tracks) {
    if (t.path != TrackPath::kWeights)
      tracks.push_back({t.path, t.interpolation, t.target, &t.times, t.values});
  }
  return tracks;
}

}  // namespace

std::size_t ModelErrorCheck::JointSamples(const Skeleton& skeleton, const RawClip& raw) {
  return CheckTimes(raw).size() * skeleton.joint_count();
}

ModelErrorCheck::ModelErrorCheck(const Skeleton& skeleton, const RawClip& raw,
                                 std::vector<StoredJointTrack> stored, double max_error_mm,
                                 double share)
    : skeleton_(skeleton),
      times_(CheckTimes(raw)),
      position_bound_(share * max_error_mm / 1000.0),
      relative_bound_(share * kRelativeError),
      rotation_bound_(share * max_error_mm / kShellDistanceMm),
      stretch_(PaletteStretch(skeleton)) {
  const uint32_t joints = skeleton.joint_count();
  subtree_.resize(joints);
  for (uint32_t j = 0; j < joints; ++j) {
    for (int p = skeleton.parents[j]; p >= 0; p = skeleton.parents[static_cast<uint32_t>(p)])
      subtree_[static_cast<uint32_t>(p)].push_back(j);
  }
  // The reference first: the original channels, then the tracks as stored.
  stored_ = OriginalTracks(raw);
  for (int pass = 0; pass < 2; ++pass) {
    joint_tracks_.assign(joints, {});
    for (uint32_t i = 0; i < stored_.size(); ++i) joint_tracks_[stored_[i].joint].push_back(i);
    Matrix& model = pass == 0 ? reference_ : model_;
    model.resize(times_.size() * joints * 12);
    local_.resize(model.size());
    for (std::size_t ti = 0; ti < times_.size(); ++ti) {
      for (uint32_t j = 0; j < joints; ++j) {
        double* local = &local_[(ti * joints + j) * 12];
        LocalOf(j, times_[ti], stored_.size(), nullptr, local);
        double* m = &model[(ti * joints + j) * 12];
        const int parent = skeleton.parents[j];
        if (parent < 0) {
          std::copy_n(local, 12, m);
        } else {
          Compose(&model[(ti * joints + static_cast<uint32_t>(parent)) * 12], local, m);
        }
      }
    }
    if (pass == 0) stored_ = std::move(stored);
  }
}

void ModelErrorCheck::LocalOf(uint32_t joint, double t, std::size_t replaced,
                              const std::vector<float>* values, double out[12]) const {
  const Transform& rest = skeleton_.rest[joint];
  double trs[3][4] = {{rest.translation[0], rest.translation[1], rest.translation[2], 0},
                      {rest.rotation[0], rest.rotation[1], rest.rotation[2], rest.rotation[3]},
                      {rest.scale[0], rest.scale[1], rest.scale[2], 0}};
  for (uint32_t i : joint_tracks_[joint]) {
    if (i == replaced) {
      StoredJointTrack track = stored_[i];
      track.values = *values;
      SampleD(track, t, trs[static_cast<int>(track.path)]);
    } else {
      SampleD(stored_[i], t, trs[static_cast<int>(stored_[i].path)]);
    }
  }
  Trs(trs[0], trs[1], trs[2], out);
}

bool ModelErrorCheck::Subtree(uint32_t joint, std::size_t ti, const double local[12], double* model,
                              bool check) const {
  const uint32_t joints = skeleton_.joint_count();
  const std::size_t base = ti * joints * 12;
  auto within = [&](uint32_t j) {
    const double* got = &model[12 * j];
    const double* want = &reference_[base + 12 * j];
    double d2 = 0, r2 = 0;
    for (int r = 0; r < 3; ++r) {
      d2 += (got[4 * r + 3] - want[4 * r + 3]) * (got[4 * r + 3] - want[4 * r + 3]);
      r2 += want[4 * r + 3] * want[4 * r + 3];
      // A row's error, so that its palette entries' elements (the row times a column of
      // the inverse bind) stay within the bound too.
      double row2 = 0;
      for (int c = 0; c < 3; ++c)
        row2 += (got[4 * r + c] - want[4 * r + c]) * (got[4 * r + c] - want[4 * r + c]);
      if (std::sqrt(row2) * stretch_[j] > rotation_bound_) return false;
    }
    return std::sqrt(d2) <= position_bound_ + relative_bound_ * std::sqrt(r2);
  };
  const int parent = skeleton_.parents[joint];
  if (parent < 0) {
    std::copy_n(local, 12, &model[12 * joint]);
  } else {
    Compose(&model_[base + 12 * static_cast<uint32_t>(parent)], local, &model[12 * joint]);
  }
  if (check && !within(joint)) return false;
  for (uint32_t j : subtree_[joint]) {  // a descendant's parent is `joint` or a descendant
    const uint32_t p = static_cast<uint32_t>(skeleton_.parents[j]);
    Compose(&model[12 * p], &local_[base + 12 * j], &model[12 * j]);
    if (check && !within(j)) return false;
  }
  return true;
}

bool ModelErrorCheck::Holds(std::size_t i, const std::vector<float>& values) const {
  const uint32_t joint = stored_[i].joint;
  std::vector<double> model(12 * skeleton_.joint_count());
  double local[12];
  for (std::size_t ti = 0; ti < times_.size(); ++ti) {
    LocalOf(joint, times_[ti], i, &values, local);
    if (!Subtree(joint, ti, local, model.data(), true)) return false;
  }
  return true;
}

void ModelErrorCheck::Accept(std::size_t i, std::vector<float> values) {
  stored_[i].values = std::move(values);
  const uint32_t joint = stored_[i].joint, joints = skeleton_.joint_count();
  std::vector<double> model(12 * joints);
  for (std::size_t ti = 0; ti < times_.size(); ++ti) {
    double* local = &local_[(ti * joints + joint) * 12];
    LocalOf(joint, times_[ti], stored_.size(), nullptr, local);
    Subtree(joint, ti, local, model.data(), false);
    std::copy_n(&model[12 * joint], 12, &model_[(ti * joints + joint) * 12]);
    for (uint32_t j : subtree_[joint])
      std::copy_n(&model[12 * j], 12, &model_[(ti * joints + j) * 12]);
  }
}

}  // namespace skinserve::animation::detail
