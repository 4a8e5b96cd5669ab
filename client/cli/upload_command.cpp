#include <fmt/format.h>

#include <optional>

#include "character_input.h"
#include "commands.h"
#include "rest_encoding_option.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {
namespace {

void PrintInfo(const std::string& name, const v1::MeshInfo& info) {
  fmt::print("{}{}{}  {} vertices, {} influences, {} joints, {} bytes{}\n", name,
             name.empty() ? "" : ": ", info.mesh_id(), info.vertex_count(), info.influences(),
             info.joint_count(), info.bytes(), info.already_stored() ? " (already stored)" : "");
}

// The whole character: one mesh per skin, its primitives concatenated with the rigid
// parts (what `animate` streams), each listed with its primitives.
int UploadCharacter(client::SkinClient& client, const std::string& path,
                    std::optional<RestEncoding> asked) {
  if (!IsGltfPath(path)) {
    return Report(InvalidArgument(fmt::format("{}: not a .glb or .gltf file", path)));
  }
  auto character = ImportCharacter(path);
  if (!character.ok()) return Report(character.status());
  auto meshes = CharacterMeshes(*character);
  if (!meshes.ok()) return Report(meshes.status());
  for (const CharacterMesh& mesh : *meshes) {
    auto rest = MeshRestEncoding(*character, mesh, asked);
    if (!rest.ok()) return Report(rest.status());
    auto info = client.Upload(mesh.arrays, {.rest_encoding = rest->encoding});
    if (!info.ok()) {
      return Report(
          Status(info.status().code(), fmt::format("{}: {}", mesh.name, info.status().message())));
    }
    PrintInfo(mesh.name, *info);
    fmt::print("  rest stream {}: {}\n", RestEncodingName(rest->encoding), rest->reason);
    for (const PrimitiveSpan& part : mesh.parts) {
      fmt::print("  {}: vertices {}..{}, {} triangles\n", part.name, part.first_vertex,
                 part.first_vertex + part.vertex_count - 1, part.index_count / 3);
    }
  }
  return 0;
}

}  // namespace

void AddUploadCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "upload",
      "upload a glTF character (FILE.glb or .gltf: one mesh per skin, its primitives and the "
      "rigid parts together), or else a synthetic mesh; prints the ids");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->Add(command);
  auto file = std::make_shared<std::string>();
  auto rest_encoding = std::make_shared<std::string>();
  AddRestEncodingOption(command, rest_encoding.get());
  command->add_option(
      "file", *file,
      "glTF 2.0 character: every skinned primitive and rigid part is uploaded, one mesh per skin "
      "(the synthetic mesh options are then ignored)");
  command->callback([&common, mesh, file, rest_encoding] {
    auto asked = ParseRestEncodingOption(*rest_encoding);
    if (!asked.ok()) {
      common.exit_code = Report(asked.status());
      return;
    }
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    if (!file->empty()) {
      common.exit_code = UploadCharacter(client, *file, *asked);
      return;
    }
    // A synthetic mesh has no file to ask: float32 unless named.
    auto info = client.Upload(MakeSyntheticMesh(mesh->spec),
                              {.rest_encoding = asked->value_or(RestEncoding::kFloat32)});
    if (!info.ok()) {
      common.exit_code = Report(info.status());
      return;
    }
    PrintInfo("", *info);
  });
}

}  // namespace skinserve::cli
