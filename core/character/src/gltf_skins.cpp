// Skins: joints and inverse bind matrices.
#include <fmt/format.h>
#include <cmath>
#include <cstddef>

#include "gltf_accessor.h"
#include "gltf_parts.h"
#include "skinserve/model/mesh.h"

namespace skinserve::gltf {

Result<std::vector<CharacterSkin>> ImportSkins(const tinygltf::Model& model) {
  std::vector<CharacterSkin> skins;
  for (std::size_t i = 0; i < model.skins.size(); ++i) {
    const tinygltf::Skin& in = model.skins[i];
    const std::string what = fmt::format("skins[{}]", i);
    CharacterSkin skin;
    skin.name = in.name;
    if (in.joints.empty()) return InvalidArgument(what + ".joints is empty; a skin needs a joint");
    // Joint indices travel as uint16 (mesh.h).
    if (in.joints.size() > kMaxJointsLimit) {
      return InvalidArgument(fmt::format("{}.joints has {} joints; at most {} are supported", what,
                                         in.joints.size(), kMaxJointsLimit));
    }
    for (std::size_t j = 0; j < in.joints.size(); ++j) {
      const int node = in.joints[j];
      if (node < 0 || static_cast<std::size_t>(node) >= model.nodes.size()) {
        return InvalidArgument(fmt::format("{}.joints[{}] = {} is not a node (the file has {})",
                                           what, j, node, model.nodes.size()));
      }
      skin.joints.push_back(node);
    }
    if (in.inverseBindMatrices < 0) {
      skin.inverse_bind.assign(skin.joints.size(), glm::mat4(1.0f));
    } else {
      const std::string field = what + ".inverseBindMatrices";
      auto reader = AccessorReader::Open(model, in.inverseBindMatrices, field, TINYGLTF_TYPE_MAT4,
                                         {TINYGLTF_COMPONENT_TYPE_FLOAT});
      if (!reader.ok()) return reader.status();
      if (reader->count() != skin.joints.size()) {
        return InvalidArgument(fmt::format("{}: accessor {} holds {} matrices; {} has {} joints",
                                           field, in.inverseBindMatrices, reader->count(), what,
                                           skin.joints.size()));
      }
      for (std::size_t j = 0; j < reader->count(); ++j) {
        glm::mat4 m;
        for (int k = 0; k < 16; ++k) {
          const float v = reader->Normalized(j, k);
          if (!std::isfinite(v)) {
            return InvalidArgument(
                fmt::format("{}[{}] element {} = {} is not finite", field, j, k, v));
          }
          m[k / 4][k % 4] = v;  // both glTF and glm are column-major
        }
        skin.inverse_bind.push_back(m);
      }
    }
    skins.push_back(std::move(skin));
  }
  return skins;
}

}  // namespace skinserve::gltf
