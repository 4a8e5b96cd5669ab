#include "skinserve/character/rest_encoding_choice.h"

#include <fmt/format.h>

namespace skinserve {
namespace {

// KHR_mesh_quantization's integer POSITION types: the 16-bit grid of the quantized stream
// holds an 8-bit one to within half its own step.
bool IsInteger(StoredType type) {
  return type == StoredType::kByte || type == StoredType::kUnsignedByte ||
         type == StoredType::kShort || type == StoredType::kUnsignedShort;
}

std::string Describe(StoredAttribute a) {
  return fmt::format("{}{}", a.normalized ? "normalized " : "", StoredTypeName(a.type));
}

}  // namespace

RestEncodingChoice RestEncodingFromFile(const Character& character,
                                        std::span<const int> primitives) {
  bool any_skinned = false, weights16 = false;
  for (int index : primitives) {
    const SkinnedPrimitive& p = character.primitives.at(static_cast<std::size_t>(index));
    if (!p.arrays.morph_target_sizes.empty()) {
      return {RestEncoding::kFloat32,
              fmt::format("{} has morph targets (a quantized rest stream carries none)", p.name)};
    }
    if (!IsInteger(p.stored.position.type)) {
      return {RestEncoding::kFloat32,
              fmt::format("{} stores POSITION as {}", p.name, Describe(p.stored.position))};
    }
    if (p.rigid()) continue;
    const StoredAttribute w = p.stored.weights;
    if (!w.normalized ||
        (w.type != StoredType::kUnsignedByte && w.type != StoredType::kUnsignedShort)) {
      return {RestEncoding::kFloat32,
              fmt::format("{} stores WEIGHTS_n as {}", p.name, Describe(w))};
    }
    any_skinned = true;
    weights16 = weights16 || w.type == StoredType::kUnsignedShort;
  }
  if (primitives.empty()) return {RestEncoding::kFloat32, "no primitive"};
  const std::string positions = "POSITION as 8- or 16-bit integers (KHR_mesh_quantization)";
  if (!any_skinned) {
    return {RestEncoding::kQuantized16, fmt::format("every part stores {}", positions)};
  }
  if (weights16) {
    return {RestEncoding::kQuantized16,
            fmt::format("every primitive stores {} and WEIGHTS_n as normalized UNSIGNED_SHORT "
                        "or UNSIGNED_BYTE",
                        positions)};
  }
  return {RestEncoding::kQuantized8Weights,
          fmt::format("every primitive stores {} and WEIGHTS_n as normalized UNSIGNED_BYTE",
                      positions)};
}

RestEncodingChoice DecideRestEncoding(std::optional<RestEncoding> asked,
                                      std::optional<RestEncodingChoice> from_file) {
  if (asked) return {*asked, "asked with --rest-encoding"};
  if (from_file) return std::move(*from_file);
  return {RestEncoding::kFloat32, "the default"};
}

}  // namespace skinserve
