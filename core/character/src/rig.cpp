#include "skinserve/character/rig.h"

#include <algorithm>
#include <iterator>

#include <fmt/format.h>

#include <cmath>
#include <functional>

namespace skinserve {
namespace {

animation::Transform ToTransform(const CharacterNode& n) {
  animation::Transform t;
  for (int c = 0; c < 3; ++c) {
    t.translation[c] = n.translation[c];
    t.scale[c] = n.scale[c];
  }
  t.rotation[0] = n.rotation.x;
  t.rotation[1] = n.rotation.y;
  t.rotation[2] = n.rotation.z;
  t.rotation[3] = n.rotation.w;
  return t;
}

// The skeleton of `palette_nodes` and their ancestors (an armature node above them moves
// them too), parents before children; palette entry p is palette_nodes[p] with
// inverse_bind[p].
Result<Rig> RigOfNodes(const Character& character, const std::vector<int>& palette_nodes,
                       std::vector<animation::Affine> inverse_bind) {
  const std::size_t n = character.nodes.size();
  std::vector<bool> wanted(n, false);
  for (int joint : palette_nodes) {
    for (int k = joint; k >= 0 && !wanted[static_cast<std::size_t>(k)];
         k = character.nodes[static_cast<std::size_t>(k)].parent) {
      wanted[static_cast<std::size_t>(k)] = true;
    }
  }
  // Depth first from the roots: each parent is placed before its children.
  std::vector<std::vector<int>> children(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int parent = character.nodes[i].parent;
    if (wanted[i] && parent >= 0)
      children[static_cast<std::size_t>(parent)].push_back(static_cast<int>(i));
  }
  Rig rig;
  std::vector<int> joint_of(n, -1);
  std::function<void(int, int)> visit = [&](int node, int parent_joint) {
    joint_of[static_cast<std::size_t>(node)] = static_cast<int>(rig.nodes.size());
    rig.nodes.push_back(node);
    const CharacterNode& cn = character.nodes[static_cast<std::size_t>(node)];
    rig.skeleton.parents.push_back(static_cast<int16_t>(parent_joint));
    rig.skeleton.rest.push_back(ToTransform(cn));
    rig.skeleton.names.push_back(cn.name);
    const int self = joint_of[static_cast<std::size_t>(node)];
    for (int child : children[static_cast<std::size_t>(node)]) visit(child, self);
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (wanted[i] && character.nodes[i].parent < 0) visit(static_cast<int>(i), -1);
  }
  for (int node : palette_nodes) {
    rig.skeleton.palette_joints.push_back(
        static_cast<uint16_t>(joint_of[static_cast<std::size_t>(node)]));
  }
  rig.skeleton.inverse_bind = std::move(inverse_bind);
  if (Status st = animation::ValidateSkeleton(rig.skeleton); !st.ok()) return st;
  return rig;
}

// The skin's inverse bind matrices as 3x4 row-major affines; INVALID_ARGUMENT naming the
// first whose last row is not 0 0 0 1.
Result<std::vector<animation::Affine>> SkinInverseBinds(const CharacterSkin& s, int skin) {
  std::vector<animation::Affine> out;
  for (std::size_t p = 0; p < s.joints.size(); ++p) {
    const glm::mat4& m = s.inverse_bind[p];  // column-major
    if (std::fabs(m[0][3]) > 1e-4f || std::fabs(m[1][3]) > 1e-4f || std::fabs(m[2][3]) > 1e-4f ||
        std::fabs(m[3][3] - 1) > 1e-4f) {
      return InvalidArgument(fmt::format(
          "skins[{}].inverseBindMatrices[{}] is not affine (last row 0 0 0 1)", skin, p));
    }
    animation::Affine a;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) a.m[4 * r + c] = m[c][r];
    }
    out.push_back(a);
  }
  return out;
}

Status CheckSkin(const Character& character, int skin) {
  if (skin < 0 || static_cast<std::size_t>(skin) >= character.skins.size()) {
    return InvalidArgument(fmt::format("skin {} is not a skin of the character (it has {})", skin,
                                       character.skins.size()));
  }
  return Status::Ok();
}

}  // namespace

Result<Rig> RigFromSkin(const Character& character, int skin) {
  if (Status s = CheckSkin(character, skin); !s.ok()) return s;
  const CharacterSkin& s = character.skins[static_cast<std::size_t>(skin)];
  auto inverse_bind = SkinInverseBinds(s, skin);
  if (!inverse_bind.ok()) return inverse_bind.status();
  return RigOfNodes(character, s.joints, *std::move(inverse_bind));
}

Result<Rig> RigFromMesh(const Character& character, const CharacterMesh& mesh) {
  std::vector<int> nodes;
  std::vector<animation::Affine> inverse_bind;
  if (mesh.skin >= 0) {
    if (Status s = CheckSkin(character, mesh.skin); !s.ok()) return s;
    const CharacterSkin& s = character.skins[static_cast<std::size_t>(mesh.skin)];
    auto binds = SkinInverseBinds(s, mesh.skin);
    if (!binds.ok()) return binds.status();
    nodes = s.joints;
    inverse_bind = *std::move(binds);
  }
  for (int node : mesh.rigid_nodes) {
    if (node < 0 || static_cast<std::size_t>(node) >= character.nodes.size()) {
      return InvalidArgument(
          fmt::format("{}: rigid node {} is not a node of the character", mesh.name, node));
    }
    nodes.push_back(node);
    inverse_bind.emplace_back();  // the rigid part's vertices are in its node's space
  }
  if (nodes.empty()) {
    return InvalidArgument(
        fmt::format("{}: no skin and no rigid part: nothing to pose", mesh.name));
  }
  return RigOfNodes(character, nodes, std::move(inverse_bind));
}
animation::RawClip RawClipFromCharacter(const AnimationClip& clip, const Rig& rig) {
  animation::RawClip raw;
  raw.name = clip.name;
  raw.duration = clip.duration;
  for (const AnimationChannel& ch : clip.channels) {
    animation::RawTrack t;
    t.interpolation = ch.interpolation == Interpolation::kStep ? animation::Interpolation::kStep
                      : ch.interpolation == Interpolation::kLinear
                          ? animation::Interpolation::kLinear
                          : animation::Interpolation::kCubicSpline;
    t.times = ch.times;
    t.values = ch.values;
    if (ch.path == ChannelPath::kWeights) {
      t.path = animation::TrackPath::kWeights;
      t.target = static_cast<uint32_t>(ch.node);
      t.width = static_cast<uint32_t>(
          ch.values.size() / ch.times.size() /
          (t.interpolation == animation::Interpolation::kCubicSpline ? 3 : 1));
    } else {
      int joint = -1;
      for (std::size_t j = 0; j < rig.nodes.size(); ++j) {
        if (rig.nodes[j] == ch.node) joint = static_cast<int>(j);
      }
      if (joint < 0) continue;
      t.target = static_cast<uint32_t>(joint);
      t.path = ch.path == ChannelPath::kTranslation ? animation::TrackPath::kTranslation
               : ch.path == ChannelPath::kRotation  ? animation::TrackPath::kRotation
                                                    : animation::TrackPath::kScale;
      t.width = t.path == animation::TrackPath::kRotation ? 4 : 3;
    }
    raw.tracks.push_back(std::move(t));
  }
  return raw;
}

animation::RawClip RawClipForMesh(const AnimationClip& clip, const Rig& rig,
                                  const CharacterMesh& mesh, bool* weights_on_server) {
  animation::RawClip raw = RawClipFromCharacter(clip, rig);
  const auto is_weights = [](const animation::RawTrack& t) {
    return t.path == animation::TrackPath::kWeights;
  };
  std::vector<animation::RawTrack> channels;  // the clip's weights channels
  std::copy_if(raw.tracks.begin(), raw.tracks.end(), std::back_inserter(channels), is_weights);
  std::erase_if(raw.tracks, is_weights);
  *weights_on_server = false;
  // The mesh's targets run node by node: each run must be one channel's weights in order.
  std::vector<animation::RawTrack> ordered;
  const std::vector<MorphTargetSource>& sources = mesh.morph_sources;
  for (std::size_t s = 0; s < sources.size();) {
    const int node = sources[s].node;
    const auto channel = std::find_if(channels.begin(), channels.end(), [&](const auto& t) {
      return static_cast<int>(t.target) == node;
    });
    if (channel == channels.end()) return raw;  // a node the clip does not key
    for (uint32_t i = 0; i < channel->width; ++i, ++s) {
      if (s >= sources.size() || sources[s].node != node || sources[s].target != i) return raw;
    }
    ordered.push_back(*channel);
  }
  if (ordered.empty()) return raw;
  raw.tracks.insert(raw.tracks.end(), ordered.begin(), ordered.end());
  *weights_on_server = true;
  return raw;
}

}  // namespace skinserve
