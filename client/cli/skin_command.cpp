#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::cli {
namespace {

struct SkinCommandOptions {
  MeshOptionsCli mesh;
  std::string backend;
  uint64_t frame = 0;
  SkinningMethod method = SkinningMethod::kLinear;
  bool shared_memory = false;
  std::string shm_dir = "/dev/shm";
};

// --shared-memory: a region for the one frame, registered with the server.
Result<std::unique_ptr<client::SharedMemoryRegion>> FrameRegion(client::SkinClient& client,
                                                                const SkinCommandOptions& o,
                                                                const MeshArrays& arrays,
                                                                const std::string& name) {
  auto made = client::SharedMemoryRegion::Create(
      name,
      wire::RegionFrameBytes(arrays.vertex_count, 1, VertexEncoding::kFloat32, o.mesh.spec.normals,
                             o.mesh.spec.tangents),
      o.shm_dir);
  if (!made.ok()) return made.status();
  std::unique_ptr<client::SharedMemoryRegion> region = std::move(made).value();
  if (auto registered = client.RegisterRegion(name, *region); !registered.ok()) {
    return registered.status();
  }
  return region;
}

// The frame against the float64 reference: its timings, its first vertex and the largest
// errors; exit status 1 outside the tolerance.
int PrintSkinned(const MeshArrays& arrays, std::span<const float> palette, SkinningMethod method,
                 const client::FrameResult& result) {
  auto local = Mesh::Create(arrays).value();
  const Deviation d = CompareWithReference(*local, palette, result.positions, result.normals,
                                           method, {}, result.tangents);
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
  return d.within_tolerance() ? 0 : 1;
}

int Skin(const CommonOptions& common, const SkinCommandOptions& o) {
  auto uploaded = UploadSynthetic(common, o.mesh.spec);
  if (!uploaded.ok()) return Report(uploaded.status());
  client::SkinClient& client = *uploaded->client;
  const MeshArrays& arrays = uploaded->arrays;
  // Dual quaternions take rigid joints only: the synthetic palettes' mild scale is refused.
  const auto palette = o.method == SkinningMethod::kDualQuaternion
                           ? MakeRigidPalette(arrays.joint_count, o.mesh.spec.seed, o.frame)
                           : MakeSyntheticPalette(arrays.joint_count, o.mesh.spec.seed, o.frame);
  client::FrameResult result;
  client::SkinOptions options{.backend = o.backend,
                              .want_normals = o.mesh.spec.normals,
                              .want_tangents = o.mesh.spec.tangents,
                              .method = o.method};
  std::unique_ptr<client::SharedMemoryRegion> region;
  const std::string region_name = client::SharedMemoryRegion::UniqueKey("cli");
  if (o.shared_memory) {
    auto made = FrameRegion(client, o, arrays, region_name);
    if (!made.ok()) return Report(made.status());
    region = std::move(made).value();
    options.output = {.name = region_name, .region = region.get()};
  }
  Status s = client.Skin(uploaded->mesh_id, palette, o.frame, options, &result);
  if (s.ok() && result.in_region()) {
    fmt::print("written into region {} ({}): {} bytes from offset 0, read in place\n", region_name,
               region->path(),
               result.region_positions.size() + result.region_normals.size() +
                   result.region_tangents.size());
    s = client::DecodeRegionFrame(&result);
  }
  if (region != nullptr) {
    if (Status u = client.UnregisterRegion(region_name); s.ok()) s = u;
  }
  if (!s.ok()) return Report(s);
  return PrintSkinned(arrays, palette, o.method, result);
}

}  // namespace

void AddSkinCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "skin", "upload a synthetic mesh, skin one frame, check it against the float64 reference");
  auto o = std::make_shared<SkinCommandOptions>();
  o->mesh.Add(command);
  AddMethodOption(command, &o->method);
  command->add_option("--backend", o->backend, "backend id (default: the server's)");
  command->add_option("--frame", o->frame, "frame number (selects the pose)")
      ->capture_default_str();
  command->add_flag("--shared-memory", o->shared_memory,
                    "have the server write the frame into a shared-memory region this command "
                    "creates and registers (the server must run on this host)");
  command->add_option("--shm-dir", o->shm_dir, "the server's --shm-dir, where the region is made")
      ->capture_default_str();
  command->callback([&common, o] { common.exit_code = Skin(common, *o); });
}

}  // namespace skinserve::cli
