#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::cli {

void AddSkinCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "skin", "upload a synthetic mesh, skin one frame, check it against the float64 reference");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->Add(command);
  auto backend = std::make_shared<std::string>();
  auto frame = std::make_shared<uint64_t>(0);
  auto method = std::make_shared<SkinningMethod>(SkinningMethod::kLinear);
  AddMethodOption(command, method.get());
  command->add_option("--backend", *backend, "backend id (default: the server's)");
  command->add_option("--frame", *frame, "frame number (selects the pose)")->capture_default_str();
  auto shared_memory = std::make_shared<bool>(false);
  auto shm_dir = std::make_shared<std::string>("/dev/shm");
  command->add_flag("--shared-memory", *shared_memory,
                    "have the server write the frame into a shared-memory region this command "
                    "creates and registers (the server must run on this host)");
  command->add_option("--shm-dir", *shm_dir, "the server's --shm-dir, where the region is made")
      ->capture_default_str();
  command->callback([&common, mesh, backend, frame, method, shared_memory, shm_dir] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    const MeshArrays arrays = MakeSyntheticMesh(mesh->spec);
    auto info = client.Upload(arrays);
    if (!info.ok()) {
      common.exit_code = Report(info.status());
      return;
    }
    // Dual quaternions take rigid joints only: the synthetic palettes' mild scale is refused.
    const auto palette = *method == SkinningMethod::kDualQuaternion
                             ? MakeRigidPalette(arrays.joint_count, mesh->spec.seed, *frame)
                             : MakeSyntheticPalette(arrays.joint_count, mesh->spec.seed, *frame);
    client::FrameResult result;
    client::SkinOptions options{.backend = *backend,
                                .want_normals = mesh->spec.normals,
                                .want_tangents = mesh->spec.tangents,
                                .method = *method};
    std::unique_ptr<client::SharedMemoryRegion> region;
    const std::string region_name = client::SharedMemoryRegion::UniqueKey("cli");
    if (*shared_memory) {
      auto made = client::SharedMemoryRegion::Create(
          region_name,
          wire::RegionFrameBytes(arrays.vertex_count, 1, VertexEncoding::kFloat32,
                                 mesh->spec.normals, mesh->spec.tangents),
          *shm_dir);
      if (!made.ok()) {
        common.exit_code = Report(made.status());
        return;
      }
      region = std::move(made).value();
      if (auto registered = client.RegisterRegion(region_name, *region); !registered.ok()) {
        common.exit_code = Report(registered.status());
        return;
      }
      options.output = {.name = region_name, .region = region.get()};
    }
    Status s = client.Skin(info->mesh_id(), palette, *frame, options, &result);
    if (s.ok() && result.in_region()) {
      fmt::print("written into region {} ({}): {} bytes from offset 0, read in place\n",
                 region_name, region->path(),
                 result.region_positions.size() + result.region_normals.size() +
                     result.region_tangents.size());
      s = client::DecodeRegionFrame(&result);
    }
    if (region != nullptr) {
      if (Status u = client.UnregisterRegion(region_name); s.ok()) s = u;
    }
    if (!s.ok()) {
      common.exit_code = Report(s);
      return;
    }
    auto local = Mesh::Create(arrays).value();
    const Deviation d = CompareWithReference(*local, palette, result.positions, result.normals,
                                             *method, {}, result.tangents);
    fmt::print("frame {}: {} vertices; queued {:.3f} ms, compute {:.3f} ms, encode {:.3f} ms\n",
               result.frame, result.positions.size() / 3, result.timing.queued_ns() / 1e6,
               result.timing.compute_ns() / 1e6, result.timing.encode_ns() / 1e6);
    fmt::print("vertex 0: ({:.5f}, {:.5f}, {:.5f})\n", result.positions[0], result.positions[1],
               result.positions[2]);
    fmt::print(
        "max error vs float64 reference: positions {:.3g} (tolerance {:.3g}), normals "
        "{:.3g}{}\n",
        d.max_position_error, d.position_tolerance, d.max_normal_error,
        result.tangents.empty() ? ""
                                : fmt::format(", tangents {:.3g} (tolerance {:.3g})",
                                              d.max_tangent_error, d.tangent_tolerance));
    common.exit_code = d.within_tolerance() ? 0 : 1;
  });
}

}  // namespace skinserve::cli
