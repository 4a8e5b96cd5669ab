#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddUploadCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("upload", "upload a synthetic mesh; prints its id");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->Add(command);
  command->callback([&common, mesh] {
    client::SkinClient client(client::MakeChannel(common.target));
    auto info = client.Upload(MakeSyntheticMesh(mesh->spec));
    if (!info.ok()) {
      common.exit_code = Report(info.status());
      return;
    }
    fmt::print("{}  {} vertices, {} influences, {} joints, {} bytes{}\n", info->mesh_id(),
               info->vertex_count(), info->influences(), info->joint_count(), info->bytes(),
               info->already_stored() ? " (already stored)" : "");
  });
}

}  // namespace skinserve::cli
