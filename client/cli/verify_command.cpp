#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"

namespace skinserve::cli {

void AddVerifyCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "verify",
      "skin a random mesh on every available backend through Skin and StreamSkin and compare "
      "with a local float64 reference; exit 1 on any mismatch");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->spec = {.vertex_count = 10'007, .influences = 4, .normals = true, .seed = 2024};
  mesh->Add(command);
  command->callback([&common, mesh] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    const MeshArrays arrays = MakeSyntheticMesh(mesh->spec);
    auto info = client.Upload(arrays);
    auto list = client.ListBackends();
    if (!info.ok() || !list.ok()) {
      common.exit_code = Report(info.ok() ? list.status() : info.status());
      return;
    }
    auto local = Mesh::Create(arrays).value();
    const bool normals = mesh->spec.normals;
    int failures = 0;
    fmt::print("{:<16} {:>8} {:>14} {:>14} {:>14}  {}\n", "backend", "frames", "max pos error",
               "max nrm error", "max tan error", "verdict");
    for (const auto& backend : list->backends()) {
      if (!backend.available() || backend.id() == "passthrough") continue;
      // --tangents: asked for back from the backends that skin them (BackendInfo.tangents).
      const bool tangents = mesh->spec.tangents && backend.tangents();
      Deviation worst;
      int frames = 0;
      Status error;
      auto check = [&](const client::FrameResult& result) {
        const auto palette = MakeSyntheticPalette(arrays.joint_count, 7, result.frame);
        const Deviation d = CompareWithReference(
            *local, palette, result.positions,
            normals ? std::span<const float>(result.normals) : std::span<const float>(),
            SkinningMethod::kLinear, {}, result.tangents);
        if (tangents && result.tangents.size() != 4ull * arrays.vertex_count) {
          error = Internal("tangents were asked for but did not come back");
        }
        ++frames;
        if (!d.within_tolerance() || d.max_position_error > worst.max_position_error) {
          worst = d;
        }
        if (!d.within_tolerance()) error = Internal("result outside tolerance");
      };
      client::FrameResult one;
      const auto palette0 = MakeSyntheticPalette(arrays.joint_count, 7, 0);
      if (Status s = client.Skin(
              info->mesh_id(), palette0, 0,
              {.backend = backend.id(), .want_normals = normals, .want_tangents = tangents}, &one);
          s.ok()) {
        check(one);
      } else {
        error = s;
      }
      client::StreamOptions options{.mesh_id = info->mesh_id(),
                                    .backend = backend.id(),
                                    .want_normals = normals,
                                    .want_tangents = tangents,
                                    .first_frame = 1,
                                    .frames = 4};
      Status streamed = client::StreamFrames(
          client, options,
          [&](uint64_t frame) { return MakeSyntheticPalette(arrays.joint_count, 7, frame); },
          [&](client::FrameResult& result, std::chrono::nanoseconds) {
            if (result.status.ok()) {
              check(result);
            } else {
              error = result.status;
            }
          });
      if (!streamed.ok()) error = streamed;
      const bool ok = error.ok() && frames == 5 && worst.within_tolerance();
      failures += ok ? 0 : 1;
      fmt::print("{:<16} {:>8} {:>14.3g} {:>14.3g} {:>14}  {}\n", backend.id(), frames,
                 worst.max_position_error, worst.max_normal_error,
                 tangents ? fmt::format("{:.3g}", worst.max_tangent_error) : "-",
                 ok ? "ok" : "MISMATCH " + error.ToString());
    }
    common.exit_code = failures == 0 ? 0 : 1;
  });
}

}  // namespace skinserve::cli
