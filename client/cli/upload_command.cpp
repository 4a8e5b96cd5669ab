#include <fmt/format.h>

#include "character_input.h"
#include "commands.h"
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
int UploadCharacter(client::SkinClient& client, const std::string& path) {
  if (!IsGltfPath(path)) {
    return Report(InvalidArgument(fmt::format("{}: not a .glb or .gltf file", path)));
  }
  auto character = ImportCharacter(path);
  if (!character.ok()) return Report(character.status());
  auto meshes = CharacterMeshes(*character);
  if (!meshes.ok()) return Report(meshes.status());
  for (const CharacterMesh& mesh : *meshes) {
    auto info = client.Upload(mesh.arrays);
    if (!info.ok()) {
      return Report(
          Status(info.status().code(), fmt::format("{}: {}", mesh.name, info.status().message())));
    }
    PrintInfo(mesh.name, *info);
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
  command->add_option(
      "file", *file,
      "glTF 2.0 character: every skinned primitive and rigid part is uploaded, one mesh per skin "
      "(the synthetic mesh options are then ignored)");
  command->callback([&common, mesh, file] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    if (!file->empty()) {
      common.exit_code = UploadCharacter(client, *file);
      return;
    }
    auto info = client.Upload(MakeSyntheticMesh(mesh->spec));
    if (!info.ok()) {
      common.exit_code = Report(info.status());
      return;
    }
    PrintInfo("", *info);
  });
}

}  // namespace skinserve::cli
