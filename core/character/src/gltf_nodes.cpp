// Node hierarchy and local transforms.
#include <fmt/format.h>
#include <cmath>
#include <cstddef>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "gltf_parts.h"

namespace skinserve::gltf {
namespace {

Status CheckFinite(const std::vector<double>& values, const std::string& what) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return InvalidArgument(fmt::format("{}[{}] = {} is not finite", what, i, values[i]));
    }
  }
  return Status::Ok();
}

Status CheckSize(const std::vector<double>& values, std::size_t expected, const std::string& what) {
  if (values.empty() || values.size() == expected) return Status::Ok();
  return InvalidArgument(
      fmt::format("{} has {} numbers; expected {}", what, values.size(), expected));
}

// A column-major 4x4 matrix split into T * R * S, which the spec requires it to be (no
// shear, no projection): anything else cannot be animated by TRS channels, so it is refused
// rather than approximated.
Status DecomposeMatrix(const std::vector<double>& m, const std::string& what, CharacterNode* node) {
  constexpr double kTolerance = 1e-4;
  if (std::fabs(m[3]) > kTolerance || std::fabs(m[7]) > kTolerance ||
      std::fabs(m[11]) > kTolerance || std::fabs(m[15] - 1.0) > kTolerance) {
    return InvalidArgument(fmt::format(
        "{}: the last row is ({}, {}, {}, {}); a node matrix must be affine (0, 0, 0, 1)", what,
        m[3], m[7], m[11], m[15]));
  }
  glm::dmat3 r;
  double s[3];
  for (int c = 0; c < 3; ++c) {
    const glm::dvec3 column(m[4 * c], m[4 * c + 1], m[4 * c + 2]);
    s[c] = glm::length(column);
    if (!(s[c] > 1e-12)) {
      return InvalidArgument(
          fmt::format("{}: column {} is zero; a node matrix must be invertible", what, c));
    }
    r[c] = column / s[c];
  }
  if (glm::determinant(r) < 0) {  // a mirror: one negative scale keeps R a rotation
    s[0] = -s[0];
    r[0] = -r[0];
  }
  const glm::dmat3 should_be_identity = glm::transpose(r) * r;
  for (int c = 0; c < 3; ++c) {
    for (int row = 0; row < 3; ++row) {
      if (std::fabs(should_be_identity[c][row] - (c == row ? 1.0 : 0.0)) > kTolerance) {
        return InvalidArgument(fmt::format(
            "{}: the matrix has shear; a node matrix must be translation * rotation * scale",
            what));
      }
    }
  }
  node->translation = glm::vec3(glm::dvec3(m[12], m[13], m[14]));
  node->rotation = glm::quat(glm::normalize(glm::quat_cast(r)));
  node->scale = glm::vec3(glm::dvec3(s[0], s[1], s[2]));
  return Status::Ok();
}

Status ReadTransform(const tinygltf::Node& n, const std::string& what, CharacterNode* node) {
  if (!n.matrix.empty()) {
    if (Status s = CheckSize(n.matrix, 16, what + ".matrix"); !s.ok()) return s;
    if (Status s = CheckFinite(n.matrix, what + ".matrix"); !s.ok()) return s;
    return DecomposeMatrix(n.matrix, what + ".matrix", node);
  }
  for (const auto& [values, size, field] :
       {std::tuple{&n.translation, 3, "translation"}, std::tuple{&n.rotation, 4, "rotation"},
        std::tuple{&n.scale, 3, "scale"}}) {
    if (Status s = CheckSize(*values, static_cast<std::size_t>(size), what + "." + field); !s.ok())
      return s;
    if (Status s = CheckFinite(*values, what + "." + field); !s.ok()) return s;
  }
  if (!n.translation.empty()) {
    node->translation = glm::vec3(glm::dvec3(n.translation[0], n.translation[1], n.translation[2]));
  }
  if (!n.scale.empty()) node->scale = glm::vec3(glm::dvec3(n.scale[0], n.scale[1], n.scale[2]));
  if (!n.rotation.empty()) {
    // glTF stores x y z w; glm's constructor takes w first.
    const glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
    const double length = glm::length(q);
    if (!(length > 1e-12)) {
      return InvalidArgument(fmt::format("{}.rotation is the zero quaternion", what));
    }
    // Unit by the spec; exporters round, and a non-unit quaternion would scale.
    node->rotation = glm::quat(q / length);
  }
  return Status::Ok();
}

}  // namespace

Result<std::vector<CharacterNode>> ImportNodes(const tinygltf::Model& model) {
  const std::size_t count = model.nodes.size();
  std::vector<CharacterNode> nodes(count);
  for (std::size_t i = 0; i < count; ++i) {
    const tinygltf::Node& n = model.nodes[i];
    const std::string what = fmt::format("nodes[{}]", i);
    nodes[i].name = n.name;
    if (Status s = ReadTransform(n, what, &nodes[i]); !s.ok()) return s;
  }
  for (std::size_t i = 0; i < count; ++i) {
    const std::vector<int>& children = model.nodes[i].children;
    for (std::size_t k = 0; k < children.size(); ++k) {
      const int child = children[k];
      if (child < 0 || static_cast<std::size_t>(child) >= count) {
        return InvalidArgument(
            fmt::format("nodes[{}].children[{}] = {} is not a node (the file "
                        "has {})",
                        i, k, child, count));
      }
      CharacterNode& c = nodes[static_cast<std::size_t>(child)];
      if (c.parent != -1) {
        return InvalidArgument(fmt::format(
            "nodes[{}] is a child of both nodes[{}] and nodes[{}]; a node has one parent", child,
            c.parent, i));
      }
      c.parent = static_cast<int>(i);
    }
  }
  // Every node has at most one parent now, so a cycle is a walk up that never reaches a
  // root. Each node is walked once: 1 = on the current walk, 2 = known to reach a root.
  std::vector<char> state(count, 0);
  std::vector<std::size_t> walk;
  for (std::size_t start = 0; start < count; ++start) {
    walk.clear();
    int n = static_cast<int>(start);
    while (n != -1 && state[static_cast<std::size_t>(n)] == 0) {
      state[static_cast<std::size_t>(n)] = 1;
      walk.push_back(static_cast<std::size_t>(n));
      n = nodes[static_cast<std::size_t>(n)].parent;
    }
    if (n != -1 && state[static_cast<std::size_t>(n)] == 1) {
      return InvalidArgument(
          fmt::format("nodes[{}] is its own ancestor; the node hierarchy must not have cycles", n));
    }
    for (std::size_t w : walk) state[w] = 2;
  }
  return nodes;
}

}  // namespace skinserve::gltf
