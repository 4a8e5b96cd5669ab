// The rest encoding (skinserve/model/quantized_rest.h) a glTF file asks for by how it stores
// its vertices: a KHR_mesh_quantization file that already holds 8- or 16-bit positions and
// normalized integer weights gets the quantized rest stream, a float file stays float32.
// Tools use it when the user did not choose one (an explicit choice always wins).
#pragma once

#include <optional>
#include <span>
#include <string>

#include "skinserve/character/character.h"
#include "skinserve/model/quantized_rest.h"

namespace skinserve {

struct RestEncodingChoice {
  RestEncoding encoding = RestEncoding::kFloat32;
  std::string reason;  // one line: what in the file decided it
};

// Over `primitives` (indices into character.primitives, the ones uploaded together):
//  - float32 when one of them has morph targets (a quantized rest stream carries none),
//    stores POSITION as FLOAT (anything but BYTE, UNSIGNED_BYTE, SHORT or UNSIGNED_SHORT,
//    normalized or not), or, when
//    skinned, WEIGHTS_n as anything but normalized UNSIGNED_BYTE or UNSIGNED_SHORT; the
//    reason names the first such primitive and its type;
//  - else quantized8-weights when every skinned one stores its weights as UNSIGNED_BYTE,
//    quantized16 otherwise (some UNSIGNED_SHORT, or only rigid parts, whose weight is 1).
RestEncodingChoice RestEncodingFromFile(const Character& character,
                                        std::span<const int> primitives);

// The rest encoding a tool uploads a mesh in, with why, in the one order every tool follows:
// `asked` (--rest-encoding: an explicit choice always wins); else `from_file`
// (RestEncodingFromFile; nullopt: not from a file); else float32, the default. Tangents do
// not decide it: every backend that reads the quantized stream skins its tangents.
RestEncodingChoice DecideRestEncoding(std::optional<RestEncoding> asked,
                                      std::optional<RestEncodingChoice> from_file);

}  // namespace skinserve
