// skinserve-cli animate: a glTF character's clip, skinned by the server frame by frame,
// written as OBJ meshes and optionally PNG images and a contact sheet.
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>

#include "character_input.h"
#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/core/character/animation.h"
#include "skinserve/render/character_camera.h"
#include "skinserve/render/contact_sheet.h"
#include "skinserve/render/mesh_renderer.h"
#include "skinserve/render/obj_writer.h"

namespace skinserve::cli {
namespace {

struct AnimateOptions {
  std::string file;
  std::string clip;
  double fps = 30;
  double seconds = 0;  // 0: the clip's duration
  std::string backend;
  SkinningMethod method = SkinningMethod::kLinear;
  std::string out;
  bool render = false;
  int width = 640, height = 640;
  int primitive = 0;
  int window = 4;
  int sheet_frames = 8;
  render::SheetOptions sheet;
};

Status CheckOptions(const AnimateOptions& o) {
  if (!(o.fps > 0 && o.fps <= 1000)) {
    return InvalidArgument(fmt::format("--fps {} is not within (0, 1000]", o.fps));
  }
  if (!(o.seconds >= 0 && o.seconds <= 3600)) {
    return InvalidArgument(fmt::format("--seconds {} is not within [0, 3600]", o.seconds));
  }
  for (const auto& [name, value] : {std::pair{"--width", o.width}, std::pair{"--height", o.height},
                                    std::pair{"--sheet-width", o.sheet.width}}) {
    if (value < 16 || value > 8192) {
      return InvalidArgument(fmt::format("{} {} is not within 16..8192", name, value));
    }
  }
  if (o.window < 1 || o.window > 1024) {
    return InvalidArgument(fmt::format("--window {} is not within 1..1024", o.window));
  }
  if (o.sheet_frames < 1 || o.sheet.columns < 1) {
    return InvalidArgument(fmt::format("--sheet-frames {} and --sheet-columns {} must be >= 1",
                                       o.sheet_frames, o.sheet.columns));
  }
  return Status::Ok();
}

std::string FrameLabel(uint64_t frame, double fps) {
  return fmt::format("frame {}  t = {:.3f} s", frame, static_cast<double>(frame) / fps);
}

int Animate(const CommonOptions& common, const AnimateOptions& o) {
  if (Status s = CheckOptions(o); !s.ok()) return Report(s);
  auto character = ImportCharacter(o.file);
  if (!character.ok()) return Report(character.status());
  auto picked = PickPrimitive(*character, o.primitive, o.file);
  if (!picked.ok()) return Report(picked.status());
  const SkinnedPrimitive& primitive = **picked;
  auto clip = PickClip(*character, o.clip, o.file);
  if (!clip.ok()) return Report(clip.status());

  // Frame i shows time i / fps; `seconds` of them, at least one.
  const double seconds = o.seconds > 0 ? o.seconds : (*clip)->duration;
  const uint64_t frames = std::max<uint64_t>(1, std::llround(seconds * o.fps));
  // Sampled as frames are sent (a long clip of a big skeleton would not fit in memory);
  // frame 0 first, so that a palette error shows before anything is uploaded.
  auto palette_at = [&](uint64_t i) {
    return SkinPalette(*character, SampleClip(*character, **clip, i / o.fps), primitive.skin);
  };
  if (auto first = palette_at(0); !first.ok()) return Report(first.status());
  std::optional<render::Camera> camera;
  if (o.render) {
    auto rest = render::RestPoseCamera(*character, primitive, o.width, o.height);
    if (!rest.ok()) return Report(rest.status());
    camera = *rest;
  }
  std::error_code error;
  std::filesystem::create_directories(o.out, error);
  if (error) {
    return Report(Internal(fmt::format("--out {}: cannot create: {}", o.out, error.message())));
  }

  client::SkinClient client(client::MakeChannel(common.target));
  auto info = client.Upload(primitive.arrays);
  if (!info.ok()) return Report(info.status());
  fmt::print("{}: {}  {} vertices, {} joints, {} triangles; clip '{}' ({:.3f} s)\n", primitive.name,
             info->mesh_id(), info->vertex_count(), info->joint_count(),
             primitive.indices.size() / 3, (*clip)->name, (*clip)->duration);

  // Files are written as answers arrive; the first failure (a palette's, a frame's or a
  // file's) stops sending and is reported. StreamFrames calls the palette source and the
  // sink on this thread.
  std::atomic<bool> stop{false};
  Status first_error;
  uint64_t written_obj = 0, written_png = 0;
  double compute_ms = 0;
  auto fail = [&](Status s) {
    if (first_error.ok()) first_error = std::move(s);
    stop = true;
  };
  client::StreamOptions stream{.mesh_id = info->mesh_id(),
                               .backend = o.backend,
                               .want_normals = !primitive.arrays.normals.empty(),
                               .method = o.method,
                               .frames = frames,
                               .window = o.window,
                               .stop = &stop};
  client::StreamSummary summary;
  const auto started = std::chrono::steady_clock::now();
  Status streamed = client::StreamFrames(
      client, stream,
      [&](uint64_t f) {
        auto palette = palette_at(f);
        if (palette.ok()) return std::move(*palette);
        fail(palette.status());  // the server rejects the empty palette; we stop sending
        return std::vector<float>();
      },
      [&](client::FrameResult& result, std::chrono::nanoseconds) {
        if (!result.status.ok()) {
          return fail(Status(result.status.code(),
                             fmt::format("frame {}: {}", result.frame, result.status.message())));
        }
        if (!first_error.ok()) return;
        compute_ms += result.timing.compute_ns() / 1e6;
        Status s = render::WriteObj(render::FrameFileName(o.out, result.frame, "obj"),
                                    result.positions, result.normals, primitive.indices);
        if (!s.ok()) return fail(s);
        ++written_obj;
        if (!camera) return;
        // Unlabelled: the frames play as a sequence; the contact sheet labels its cells.
        s = render::RenderPng(render::FrameFileName(o.out, result.frame, "png"), *camera,
                              result.positions, primitive.indices);
        if (!s.ok()) return fail(s);
        ++written_png;
      },
      &summary);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if (!streamed.ok()) return Report(streamed);
  if (!first_error.ok()) return Report(first_error);
  if (summary.answered != frames) {
    return Report(Internal(fmt::format("{} of {} frames answered", summary.answered, frames)));
  }

  std::string sheet_note;
  if (camera) {
    std::vector<render::SheetFrame> sheet;
    for (std::size_t i : render::EvenlySpaced(frames, static_cast<std::size_t>(o.sheet_frames))) {
      sheet.push_back({render::FrameFileName(o.out, i, "png"), FrameLabel(i, o.fps)});
    }
    const std::string path = o.out + "/contact-sheet.png";
    if (Status s = render::WriteContactSheet(path, sheet, o.sheet); !s.ok()) return Report(s);
    sheet_note = fmt::format(", {} PNG frames and {} ({} frames)", written_png, path, sheet.size());
  }
  fmt::print(
      "{} frames ({:.3f} s at {} fps) on {}: {:.2f} s, {:.1f} frames/s with files written, "
      "server compute {:.3f} ms/frame\nwrote {} OBJ frames{} in {}\n",
      frames, static_cast<double>(frames) / o.fps, o.fps,
      o.backend.empty() ? "the default backend" : o.backend, elapsed, frames / elapsed,
      compute_ms / static_cast<double>(frames), written_obj, sheet_note, o.out);
  return 0;
}

}  // namespace

void AddAnimateCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "animate",
      "skin a glTF character's clip on the server frame by frame; write DIR/frame_NNNN.obj "
      "(and with --render .png and contact-sheet.png)");
  auto o = std::make_shared<AnimateOptions>();
  command->add_option("file", o->file, "glTF 2.0 character (.glb, or .gltf with its buffers)")
      ->required();
  command->add_option("--clip", o->clip, "animation clip name (default: the file's first)");
  command->add_option("--fps", o->fps, "frames per second of clip time")->capture_default_str();
  command->add_option("--seconds", o->seconds, "clip time to cover (default: the clip's duration)");
  command->add_option("--backend", o->backend, "backend id (default: the server's)");
  AddMethodOption(command, &o->method);
  command->add_option("--out", o->out, "output directory (created if missing)")->required();
  command->add_flag("--render", o->render,
                    "also draw each frame as PNG (Cairo, fixed camera) and a contact sheet");
  command->add_option("--width", o->width, "PNG width")->capture_default_str();
  command->add_option("--height", o->height, "PNG height")->capture_default_str();
  command->add_option("--primitive", o->primitive, "which skinned primitive of the file")
      ->capture_default_str();
  command->add_option("--window", o->window, "frames in flight")->capture_default_str();
  command
      ->add_option("--sheet-frames", o->sheet_frames, "frames on the contact sheet, evenly spaced")
      ->capture_default_str();
  command->add_option("--sheet-columns", o->sheet.columns, "contact sheet columns")
      ->capture_default_str();
  command->add_option("--sheet-width", o->sheet.width, "contact sheet width in pixels")
      ->capture_default_str();
  command->callback([&common, o] { common.exit_code = Animate(common, *o); });
}

}  // namespace skinserve::cli
