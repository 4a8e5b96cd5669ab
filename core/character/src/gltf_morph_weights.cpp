// Morph target weights of mesh nodes: what a frame weighs each target by when no
// animation channel says otherwise.
#include <fmt/format.h>

#include "gltf_parts.h"
#include "skinserve/model/morph_targets.h"

namespace skinserve::gltf {

Status ImportMorphWeights(const tinygltf::Model& model, std::vector<CharacterNode>* nodes) {
  for (std::size_t n = 0; n < model.nodes.size() && n < nodes->size(); ++n) {
    const tinygltf::Node& node = model.nodes[n];
    if (node.mesh < 0 || static_cast<std::size_t>(node.mesh) >= model.meshes.size()) continue;
    const tinygltf::Mesh& mesh = model.meshes[static_cast<std::size_t>(node.mesh)];
    // The spec: every primitive of a mesh has the same number of targets.
    const std::size_t targets = mesh.primitives.empty() ? 0 : mesh.primitives[0].targets.size();
    for (std::size_t p = 1; p < mesh.primitives.size(); ++p) {
      if (mesh.primitives[p].targets.size() != targets) {
        return InvalidArgument(fmt::format(
            "meshes[{}].primitives[{}] has {} morph targets, primitives[0] {}; a mesh's "
            "primitives must have the same number",
            node.mesh, p, mesh.primitives[p].targets.size(), targets));
      }
    }
    if (targets > kMaxMorphTargets) {
      return InvalidArgument(fmt::format("meshes[{}]: {} morph targets; at most {}", node.mesh,
                                         targets, kMaxMorphTargets));
    }
    const std::vector<double>& given = !node.weights.empty() ? node.weights : mesh.weights;
    const std::string field = !node.weights.empty() ? fmt::format("nodes[{}].weights", n)
                                                    : fmt::format("meshes[{}].weights", node.mesh);
    if (!given.empty() && given.size() != targets) {
      return InvalidArgument(fmt::format("{} holds {} weights; the mesh has {} morph targets",
                                         field, given.size(), targets));
    }
    std::vector<float>& weights = (*nodes)[n].weights;
    weights.assign(targets, 0.0f);
    for (std::size_t t = 0; t < given.size(); ++t) weights[t] = static_cast<float>(given[t]);
  }
  return Status::Ok();
}

}  // namespace skinserve::gltf
