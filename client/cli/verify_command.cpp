#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"

namespace skinserve::cli {
namespace {

// One backend's frames against the float64 reference: the worst deviation, the frames
// checked and the first error (a frame's, a stream's, or one outside the tolerance).
struct BackendCheck {
  Deviation worst;
  int frames = 0;
  Status error;
};

// Frame 0 through Skin, frames 1 to 4 through StreamSkin, each against the reference.
BackendCheck CheckBackend(client::SkinClient& client, const SyntheticUpload& mesh,
                          const Mesh& local, const std::string& backend, bool normals,
                          bool tangents) {
  const MeshArrays& arrays = mesh.arrays;
  BackendCheck c;
  auto check = [&](const client::FrameResult& result) {
    const auto palette = MakeSyntheticPalette(arrays.joint_count, 7, result.frame);
    const Deviation d = CompareWithReference(
        local, palette, result.positions,
        normals ? std::span<const float>(result.normals) : std::span<const float>(),
        SkinningMethod::kLinear, {}, result.tangents);
    if (tangents && result.tangents.size() != 4ull * arrays.vertex_count) {
      c.error = Internal("tangents were asked for but did not come back");
    }
    ++c.frames;
    if (!d.within_tolerance() || d.max_position_error > c.worst.max_position_error) c.worst = d;
    if (!d.within_tolerance()) c.error = Internal("result outside tolerance");
  };
  client::FrameResult one;
  const auto palette0 = MakeSyntheticPalette(arrays.joint_count, 7, 0);
  if (Status s = client.Skin(
          mesh.mesh_id, palette0, 0,
          {.backend = backend, .want_normals = normals, .want_tangents = tangents}, &one);
      s.ok()) {
    check(one);
  } else {
    c.error = s;
  }
  client::StreamOptions options{.mesh_id = mesh.mesh_id,
                                .backend = backend,
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
          c.error = result.status;
        }
      });
  if (!streamed.ok()) c.error = streamed;
  return c;
}

int Verify(const CommonOptions& common, const MeshOptionsCli& mesh) {
  auto uploaded = UploadSynthetic(common, mesh.spec);
  if (!uploaded.ok()) return Report(uploaded.status());
  client::SkinClient& client = *uploaded->client;
  auto list = client.ListBackends();
  if (!list.ok()) return Report(list.status());
  auto local = Mesh::Create(uploaded->arrays).value();
  int failures = 0;
  fmt::print("{:<16} {:>8} {:>14} {:>14} {:>14}  {}\n", "backend", "frames", "max pos error",
             "max nrm error", "max tan error", "verdict");
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    // --tangents: asked for back from the backends that skin them (BackendInfo.tangents).
    const bool tangents = mesh.spec.tangents && backend.tangents();
    const BackendCheck c =
        CheckBackend(client, *uploaded, *local, backend.id(), mesh.spec.normals, tangents);
    const bool ok = c.error.ok() && c.frames == 5 && c.worst.within_tolerance();
    failures += ok ? 0 : 1;
    fmt::print("{:<16} {:>8} {:>14.3g} {:>14.3g} {:>14}  {}\n", backend.id(), c.frames,
               c.worst.max_position_error, c.worst.max_normal_error,
               tangents ? fmt::format("{:.3g}", c.worst.max_tangent_error) : "-",
               ok ? "ok" : "MISMATCH " + c.error.ToString());
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace

void AddVerifyCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "verify",
      "skin a random mesh on every available backend through Skin and StreamSkin and compare "
      "with a local float64 reference; exit 1 on any mismatch");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->spec = {.vertex_count = 10'007, .influences = 4, .normals = true, .seed = 2024};
  mesh->Add(command);
  command->callback([&common, mesh] { common.exit_code = Verify(common, *mesh); });
}

}  // namespace skinserve::cli
