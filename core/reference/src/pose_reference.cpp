#include "skinserve/reference/pose_reference.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace skinserve {
namespace {

using animation::Interpolation;
using animation::RawTrack;
using animation::TrackPath;

// A joint's local translation, rotation (x y z w) and scale in double.
struct Local {
  std::array<double, 3> t;
  std::array<double, 4> r;
  std::array<double, 3> s;
};

// Row-major 3x4; the last row is 0 0 0 1.
using Mat = std::array<double, 12>;

// Key k's part (CUBICSPLINE: 0 in-tangent, 1 value, 2 out-tangent; else the value) of a track.
std::vector<double> Key(const RawTrack& track, std::size_t k, std::size_t part) {
  const bool cubic = track.interpolation == Interpolation::kCubicSpline;
  const std::size_t at = (cubic ? 3 * k + part : k) * track.width;
  return {track.values.begin() + static_cast<std::ptrdiff_t>(at),
          track.values.begin() + static_cast<std::ptrdiff_t>(at + track.width)};
}

// Slerp from a to b by u, b flipped onto a's hemisphere (glTF's shortest path).
std::vector<double> Slerp(const std::vector<double>& a, std::vector<double> b, double u) {
  double dot = 0;
  for (int c = 0; c < 4; ++c) dot += a[c] * b[c];
  if (dot < 0) {
    for (double& x : b) x = -x;
    dot = -dot;
  }
  const double theta = std::acos(std::min(1.0, dot));
  std::vector<double> out(4);
  for (int c = 0; c < 4; ++c) {
    out[c] = theta < 1e-9 ? a[c] + u * (b[c] - a[c])
                          : (std::sin((1 - u) * theta) * a[c] + std::sin(u * theta) * b[c]) /
                                std::sin(theta);
  }
  return out;
}

// The track at `t`, clamped to its end keys; rotations normalised.
std::vector<double> Sample(const RawTrack& track, double t) {
  const std::size_t keys = track.times.size();
  std::vector<double> out;
  if (t <= track.times.front()) {
    out = Key(track, 0, 1);
  } else if (t >= track.times.back()) {
    out = Key(track, keys - 1, 1);
  } else {
    std::size_t k = 0;
    while (!(track.times[k] <= t && t < track.times[k + 1])) ++k;
    const double t0 = track.times[k], d = double{track.times[k + 1]} - t0, u = (t - t0) / d;
    const std::vector<double> a = Key(track, k, 1), b = Key(track, k + 1, 1);
    out = a;
    if (track.interpolation == Interpolation::kCubicSpline) {
      const std::vector<double> m0 = Key(track, k, 2), m1 = Key(track, k + 1, 0);
      for (std::size_t c = 0; c < out.size(); ++c) {
        out[c] = (2 * u * u * u - 3 * u * u + 1) * a[c] + (u * u * u - 2 * u * u + u) * d * m0[c] +
                 (-2 * u * u * u + 3 * u * u) * b[c] + (u * u * u - u * u) * d * m1[c];
      }
    } else if (track.interpolation == Interpolation::kLinear && track.width == 4) {
      out = Slerp(a, b, u);
    } else if (track.interpolation == Interpolation::kLinear) {
      for (std::size_t c = 0; c < out.size(); ++c) out[c] = a[c] + u * (b[c] - a[c]);
    }
  }
  if (track.path == TrackPath::kRotation) {
    double length = 0;
    for (double x : out) length += x * x;
    for (double& x : out) x /= std::sqrt(length);
  }
  return out;
}

// T * R * S.
Mat Compose(const Local& l) {
  const double x = l.r[0], y = l.r[1], z = l.r[2], w = l.r[3];
  const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                       2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
  Mat m{};
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m[4 * row + col] = r[3 * row + col] * l.s[col];
    m[4 * row + 3] = l.t[row];
  }
  return m;
}

Mat Multiply(const Mat& a, const Mat& b) {
  Mat o{};
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 4; ++col) {
      for (int k = 0; k < 3; ++k) o[4 * row + col] += a[4 * row + k] * b[4 * k + col];
    }
    o[4 * row + 3] += a[4 * row + 3];
  }
  return o;
}

// Every joint's local transform at `time`: the rest pose, then the clip's tracks.
std::vector<Local> LocalPose(const animation::Skeleton& skeleton, const animation::RawClip& clip,
                             double time) {
  std::vector<Local> local(skeleton.joint_count());
  for (std::size_t j = 0; j < local.size(); ++j) {
    const animation::Transform& rest = skeleton.rest[j];
    std::copy_n(rest.translation, 3, local[j].t.begin());
    std::copy_n(rest.rotation, 4, local[j].r.begin());
    std::copy_n(rest.scale, 3, local[j].s.begin());
  }
  for (const RawTrack& track : clip.tracks) {
    if (track.path == TrackPath::kWeights || track.times.empty()) continue;
    const std::vector<double> v = Sample(track, time);
    Local& l = local[track.target];
    double* out = track.path == TrackPath::kTranslation ? l.t.data()
                  : track.path == TrackPath::kRotation  ? l.r.data()
                                                        : l.s.data();
    std::copy(v.begin(), v.end(), out);
  }
  return local;
}

}  // namespace

std::vector<double> ReferencePosePalette(const animation::Skeleton& skeleton,
                                         const animation::RawClip& clip, double time) {
  const std::vector<Local> local = LocalPose(skeleton, clip, time);
  std::vector<Mat> model(local.size());
  for (std::size_t j = 0; j < local.size(); ++j) {
    const int parent = skeleton.parents[j];  // parents come before their children
    model[j] = parent < 0 ? Compose(local[j])
                          : Multiply(model[static_cast<std::size_t>(parent)], Compose(local[j]));
  }
  std::vector<double> palette;
  palette.reserve(12 * skeleton.palette_size());
  for (std::size_t p = 0; p < skeleton.palette_size(); ++p) {
    Mat inverse_bind;
    std::copy_n(skeleton.inverse_bind[p].m, 12, inverse_bind.begin());
    const Mat entry = Multiply(model[skeleton.palette_joints[p]], inverse_bind);
    palette.insert(palette.end(), entry.begin(), entry.end());
  }
  return palette;
}

}  // namespace skinserve
