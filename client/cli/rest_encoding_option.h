// skinserve-cli's --rest-encoding (upload, animate): how the server stores a mesh's rest
// stream (docs/backends/quantized-rest.md). "auto", the default, takes what a glTF file's
// storage asks for (RestEncodingFromFile: a KHR_mesh_quantization file with 16-bit
// positions and normalized integer weights gets the quantized stream); a name always wins.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "skinserve/character/character.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/rest_encoding_choice.h"
#include "skinserve/model/status.h"

namespace skinserve::cli {

// Adds --rest-encoding to `command`, into `value` ("auto" unless given).
void AddRestEncodingOption(CLI::App* command, std::string* value);

// The encoding named by `value`, nullopt for "auto", or INVALID_ARGUMENT naming the option and
// the accepted names.
Result<std::optional<RestEncoding>> ParseRestEncodingOption(const std::string& value);

// The encoding `mesh` goes up in, with why: DecideRestEncoding over the file's choice for
// the mesh's parts (the asked one; else the file's).
// INVALID_ARGUMENT, naming the mesh, for a quantized encoding asked of a mesh with morph
// targets.
Result<RestEncodingChoice> MeshRestEncoding(const Character& character, const CharacterMesh& mesh,
                                            std::optional<RestEncoding> asked);

}  // namespace skinserve::cli
