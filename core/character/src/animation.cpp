#include "skinserve/character/animation.h"

#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>

#include "skinserve/model/palette.h"

namespace skinserve {
namespace {

std::size_t Width(ChannelPath path) { return path == ChannelPath::kRotation ? 4 : 3; }

// Shortest-path spherical interpolation of unit quaternions stored x y z w. Computed in
// double, so plain slerp stays accurate down to tiny angles; only (nearly) equal keys fall
// back to a normalised lerp, where both agree to double rounding.
void Slerp(const float* a, const float* b, double u, double out[4]) {
  double dot = 0;
  for (int c = 0; c < 4; ++c) dot += double{a[c]} * b[c];
  const double sign = dot < 0 ? -1.0 : 1.0;  // q and -q are one rotation: take the short way
  dot *= sign;
  double wa = 1.0 - u;
  double wb = u;
  if (dot < 1.0 - 1e-12) {
    const double theta = std::acos(std::min(dot, 1.0));
    const double sin_theta = std::sin(theta);
    wa = std::sin((1.0 - u) * theta) / sin_theta;
    wb = std::sin(u * theta) / sin_theta;
  }
  double length = 0;
  for (int c = 0; c < 4; ++c) {
    out[c] = wa * a[c] + wb * sign * b[c];
    length += out[c] * out[c];
  }
  length = std::sqrt(length);
  for (int c = 0; c < 4; ++c) out[c] /= length;
}

// True when the channel's arrays are consistent with its interpolation: importer output
// always is; a hand-built Character that is not animates nothing through this channel
// rather than reading out of bounds.
bool IsWellFormed(const AnimationChannel& ch, std::size_t node_count) {
  const std::size_t per_key =
      Width(ch.path) * (ch.interpolation == Interpolation::kCubicSpline ? 3 : 1);
  return ch.node >= 0 && static_cast<std::size_t>(ch.node) < node_count && !ch.times.empty() &&
         ch.values.size() == ch.times.size() * per_key;
}

// The channel's value at `t` per the glTF spec (Appendix C, "Interpolation").
void SampleChannel(const AnimationChannel& ch, double t, double out[4]) {
  const std::size_t n = Width(ch.path);
  const bool cubic = ch.interpolation == Interpolation::kCubicSpline;
  // CUBICSPLINE keys are (in-tangent, value, out-tangent).
  auto value = [&](std::size_t k) { return &ch.values[(cubic ? 3 * k + 1 : k) * n]; };
  if (std::isnan(t)) {  // propagates, so that SkinPalette reports a non-finite palette
    for (std::size_t c = 0; c < n; ++c) out[c] = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  const std::vector<float>& times = ch.times;
  t = std::clamp(t, double{times.front()}, double{times.back()});
  // k: the last key at or before t.
  const std::size_t k =
      static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t,
                                                [](double x, float key) { return x < key; }) -
                               times.begin()) -
      1;
  if (k + 1 >= times.size()) {
    for (std::size_t c = 0; c < n; ++c) out[c] = value(times.size() - 1)[c];
    return;
  }
  const double td = double{times[k + 1]} - times[k];
  const double u = (t - times[k]) / td;
  const float* v0 = value(k);
  const float* v1 = value(k + 1);
  switch (ch.interpolation) {
    case Interpolation::kStep:
      for (std::size_t c = 0; c < n; ++c) out[c] = v0[c];
      return;
    case Interpolation::kLinear:
      if (ch.path == ChannelPath::kRotation) {
        Slerp(v0, v1, u, out);
      } else {
        for (std::size_t c = 0; c < n; ++c) out[c] = (1.0 - u) * v0[c] + u * v1[c];
      }
      return;
    case Interpolation::kCubicSpline: {
      // Hermite spline; the stored tangents are per second, so they scale by the interval.
      const float* out_tangent0 = &ch.values[(3 * k + 2) * n];
      const float* in_tangent1 = &ch.values[(3 * (k + 1)) * n];
      const double u2 = u * u;
      const double u3 = u2 * u;
      const double h00 = 2 * u3 - 3 * u2 + 1;
      const double h10 = u3 - 2 * u2 + u;
      const double h01 = -2 * u3 + 3 * u2;
      const double h11 = u3 - u2;
      for (std::size_t c = 0; c < n; ++c) {
        out[c] = h00 * v0[c] + h10 * td * out_tangent0[c] + h01 * v1[c] + h11 * td * in_tangent1[c];
      }
      if (ch.path == ChannelPath::kRotation) {
        const double length =
            std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
        for (std::size_t c = 0; c < 4; ++c) out[c] /= length;
      }
      return;
    }
  }
}

// Local T * R * S in double. The rotation is normalised: the spec requires unit
// quaternions, and a slightly longer one would scale the joint.
glm::dmat4 LocalMatrix(const CharacterNode& node) {
  const glm::dquat q = glm::normalize(glm::dquat(node.rotation));
  glm::dmat4 m = glm::mat4_cast(q);
  for (int c = 0; c < 3; ++c) m[c] *= double{node.scale[c]};
  m[3] = glm::dvec4(glm::dvec3(node.translation), 1.0);
  return m;
}

}  // namespace

Pose RestPose(const Character& character) { return character.nodes; }

Pose SampleClip(const Character& character, const AnimationClip& clip, double seconds) {
  Pose pose = character.nodes;
  for (const AnimationChannel& ch : clip.channels) {
    if (!IsWellFormed(ch, pose.size())) continue;
    double v[4];
    SampleChannel(ch, seconds, v);
    CharacterNode& node = pose[static_cast<std::size_t>(ch.node)];
    switch (ch.path) {
      case ChannelPath::kTranslation:
        node.translation = glm::vec3(glm::dvec3(v[0], v[1], v[2]));
        break;
      case ChannelPath::kScale:
        node.scale = glm::vec3(glm::dvec3(v[0], v[1], v[2]));
        break;
      case ChannelPath::kRotation:
        node.rotation = glm::quat(glm::dquat(v[3], v[0], v[1], v[2]));  // file: x y z w
        break;
    }
  }
  return pose;
}

namespace {

// palette[k] = model(nodes[k]) * inverse_bind[k] (identity when `inverse_bind` is null).
// `what` and `field` name the node list in errors ("skins[0]", "joints").
Result<std::vector<float>> NodeMatrices(const Character& character, const Pose& pose,
                                        const std::vector<int>& nodes,
                                        const std::vector<glm::mat4>* inverse_bind,
                                        const std::string& what, const char* field) {
  const std::size_t node_count = character.nodes.size();
  if (pose.size() != node_count) {
    return InvalidArgument(
        fmt::format("pose has {} nodes; the character has {}", pose.size(), node_count));
  }
  // Model matrices on demand, root down, whatever the order of nodes in the array:
  // 0 = not yet, 1 = on the current walk up (seen again: a cycle), 2 = done.
  std::vector<glm::dmat4> model(node_count);
  std::vector<char> state(node_count, 0);
  std::vector<std::size_t> walk;
  auto compute = [&](std::size_t node) -> Status {
    walk.clear();
    std::size_t n = node;
    while (state[n] != 2) {
      if (state[n] == 1) {
        return InvalidArgument(fmt::format("nodes[{}] is its own ancestor", n));
      }
      state[n] = 1;
      walk.push_back(n);
      const int parent = character.nodes[n].parent;
      if (parent == -1) break;
      if (parent < 0 || static_cast<std::size_t>(parent) >= node_count) {
        return InvalidArgument(fmt::format("nodes[{}].parent = {} is not a node (there are {})", n,
                                           parent, node_count));
      }
      n = static_cast<std::size_t>(parent);
    }
    for (auto it = walk.rbegin(); it != walk.rend(); ++it) {
      const int parent = character.nodes[*it].parent;
      const glm::dmat4 local = LocalMatrix(pose[*it]);
      model[*it] = parent == -1 ? local : model[static_cast<std::size_t>(parent)] * local;
      state[*it] = 2;
    }
    return Status::Ok();
  };

  std::vector<float> palette(kFloatsPerJoint * nodes.size());
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    const int node = nodes[j];
    if (node < 0 || static_cast<std::size_t>(node) >= node_count) {
      return InvalidArgument(fmt::format("{}.{}[{}] = {} is not a node (there are {})", what, field,
                                         j, node, node_count));
    }
    if (Status st = compute(static_cast<std::size_t>(node)); !st.ok()) return st;
    glm::dmat4 m = model[static_cast<std::size_t>(node)];
    if (inverse_bind != nullptr) m = m * glm::dmat4((*inverse_bind)[j]);
    // glm is column-major; the palette is row-major 3x4 (palette.h).
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c)
        palette[kFloatsPerJoint * j + 4 * r + c] = static_cast<float>(m[c][r]);
    }
  }
  if (Status st = ValidatePalette(palette, static_cast<uint32_t>(nodes.size())); !st.ok()) {
    return InvalidArgument(fmt::format("{}: {}", what, st.message()));
  }
  return palette;
}

}  // namespace

Result<std::vector<float>> SkinPalette(const Character& character, const Pose& pose, int skin) {
  if (skin < 0 || static_cast<std::size_t>(skin) >= character.skins.size()) {
    return InvalidArgument(fmt::format("skin {} is not a skin of the character (it has {})", skin,
                                       character.skins.size()));
  }
  const CharacterSkin& s = character.skins[static_cast<std::size_t>(skin)];
  if (s.inverse_bind.size() != s.joints.size()) {
    return InvalidArgument(fmt::format("skins[{}] has {} inverse bind matrices for {} joints", skin,
                                       s.inverse_bind.size(), s.joints.size()));
  }
  return NodeMatrices(character, pose, s.joints, &s.inverse_bind, fmt::format("skins[{}]", skin),
                      "joints");
}

Result<std::vector<float>> NodePalette(const Character& character, const Pose& pose,
                                       const std::vector<int>& nodes) {
  return NodeMatrices(character, pose, nodes, nullptr, "rigid parts", "nodes");
}

}  // namespace skinserve
