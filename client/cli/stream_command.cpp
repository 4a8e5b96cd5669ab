#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"

namespace skinserve::cli {

void AddStreamCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "stream", "stream N frames of a synthetic mesh on a backend; prints frames/s and vertices/s");
  auto mesh = std::make_shared<MeshOptionsCli>();
  mesh->Add(command);
  auto options = std::make_shared<client::StreamOptions>();
  command->add_option("--backend", options->backend, "backend id (default: the server's)");
  command->add_option("--frames", options->frames, "frames to stream")->capture_default_str();
  command->add_option("--window", options->window, "frames in flight")->capture_default_str();
  command
      ->add_option("--max-reconnects", options->max_reconnects,
                   "new streams after one ended UNAVAILABLE or idle (--stream-idle-seconds), in a "
                   "row without an answer; 0: the first such end ends the command")
      ->capture_default_str();
  AddMethodOption(command, &options->method);
  command->callback([&common, mesh, options] {
    auto uploaded = UploadSynthetic(common, mesh->spec);
    if (!uploaded.ok()) {
      common.exit_code = Report(uploaded.status());
      return;
    }
    client::SkinClient& client = *uploaded->client;
    const MeshArrays& arrays = uploaded->arrays;
    options->mesh_id = uploaded->mesh_id;
    options->want_normals = mesh->spec.normals;
    options->want_tangents = mesh->spec.tangents;
    std::vector<std::vector<float>> palettes;
    for (int i = 0; i < 16; ++i) {
      palettes.push_back(options->method == SkinningMethod::kDualQuaternion
                             ? MakeRigidPalette(arrays.joint_count, mesh->spec.seed, i)
                             : MakeSyntheticPalette(arrays.joint_count, mesh->spec.seed, i));
    }
    Status first_error;
    client::StreamSummary summary;
    const auto started = std::chrono::steady_clock::now();
    Status s = client::StreamFrames(
        client, *options, [&](uint64_t frame) { return palettes[frame % palettes.size()]; },
        [&](client::FrameResult& result, std::chrono::nanoseconds) {
          if (!result.status.ok() && first_error.ok()) first_error = result.status;
        },
        &summary);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    const double fps = summary.answered / seconds;
    const double bytes_per_frame =
        4.0 * arrays.vertex_count *
        (3 + (options->want_normals ? 3 : 0) + (options->want_tangents ? 4 : 0));
    fmt::print(
        "{}: {} frames in {:.2f} s: {:.1f} frames/s, {:.1f} M vertices/s, {:.1f} MB/s "
        "out; {} failed\n",
        options->backend.empty() ? "default backend" : options->backend, summary.answered, seconds,
        fps, fps * arrays.vertex_count / 1e6, fps * bytes_per_frame / 1e6, summary.failed);
    if (!s.ok()) {
      common.exit_code = Report(s);
    } else if (!first_error.ok()) {
      common.exit_code = Report(first_error);
    }
  });
}

}  // namespace skinserve::cli
