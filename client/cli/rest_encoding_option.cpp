#include "rest_encoding_option.h"

#include <fmt/format.h>

#include <vector>

namespace skinserve::cli {

void AddRestEncodingOption(CLI::App* command, std::string* value) {
  *value = "auto";
  command
      ->add_option("--rest-encoding", *value,
                   "how the server stores the rest stream: auto (a glTF file's storage decides: "
                   "8- or 16-bit positions and integer weights give quantized16 or "
                   "quantized8-weights), float32, quantized16, quantized8-weights")
      ->capture_default_str();
}

Result<std::optional<RestEncoding>> ParseRestEncodingOption(const std::string& value) {
  if (value == "auto") return std::optional<RestEncoding>();
  if (auto encoding = ParseRestEncoding(value)) return std::optional<RestEncoding>(*encoding);
  return InvalidArgument(fmt::format(
      "--rest-encoding '{}' is none of auto, float32, quantized16, quantized8-weights", value));
}

Result<RestEncodingChoice> MeshRestEncoding(const Character& character, const CharacterMesh& mesh,
                                            std::optional<RestEncoding> asked) {
  const bool morphs = !mesh.arrays.morph_target_sizes.empty();
  if (asked && *asked != RestEncoding::kFloat32 && morphs) {
    return InvalidArgument(fmt::format(
        "--rest-encoding {}: {} has morph targets, which a quantized rest stream does not carry",
        RestEncodingName(*asked), mesh.name));
  }
  std::vector<int> primitives;
  for (const PrimitiveSpan& part : mesh.parts) primitives.push_back(part.primitive);
  return DecideRestEncoding(asked, RestEncodingFromFile(character, primitives));
}

}  // namespace skinserve::cli
