#include <fmt/format.h>

#include "character_input.h"
#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {
namespace {

void PrintInfo(const std::string& name, const v1::MeshInfo& info) {
  fmt::print("{}{}{}  {} vertices, {} influences, {} joints, {} bytes{}\n", name,
             name.empty() ? "" : ": ", info.mesh_id(), info.vertex_count(), info.influences(),
             info.joint_count(), info.bytes(), info.already_stored() ? " (already stored)" : "");
}

// Every skinned primitive of the character, one mesh each.
int UploadCharacter(client::SkinClient& client, const std::string& path) {
  if (!IsGltfPath(path)) {
    return Report(InvalidArgument(fmt::format("{}: not a .glb or .gltf file", path)));
  }
  auto character = ImportCharacter(path);
  if (!character.ok()) return Report(character.status());
  for (const SkinnedPrimitive& primitive : character->primitives) {
    auto info = client.Upload(primitive.arrays);
    if (!info.ok()) {
      return Report(Status(info.status().code(),
                           fmt::format("{}: {}", primitive.name, info.status().message())));
    }
    PrintInfo(primitive.name, *info);
  }
  return 0;
}

}  // namespace

void AddUploadCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "upload",
      "upload a glTF character's skinned meshes (FILE.glb or .gltf), or else a synthetic mesh; "
      "prints the ids");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->Add(command);
  auto file = std::make_shared<std::string>();
  command->add_option("file", *file,
                      "glTF 2.0 character: every skinned primitive is uploaded (the synthetic "
                      "mesh options are then ignored)");
  command->callback([&common, mesh, file] {
    client::SkinClient client(client::MakeChannel(common.target));
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
