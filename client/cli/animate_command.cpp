// skinserve-cli animate: a glTF character's clip, skinned by the server frame by frame,
// written as OBJ meshes and optionally PNG images and a contact sheet. The whole character:
// one mesh per skin (its primitives concatenated), one stream per mesh, one OBJ (a group
// per primitive) and one image per frame. With --on-server the client samples nothing: it
// uploads each mesh's skeleton and clip once and every frame names the clip and its time
// (docs/serving/animation.md); the server samples the pose and makes the palette.
#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "character_input.h"
#include "commands.h"
#include "progress_line.h"
#include "rest_encoding_option.h"
#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/rig.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
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
  std::string rest_encoding = "auto";
  SkinningMethod method = SkinningMethod::kLinear;
  std::string out;
  bool render = false;
  int width = 640, height = 640;
  int primitive = -1;  // -1: the whole character
  int window = 4;
  int sheet_frames = 8;
  render::SheetOptions sheet;
  bool on_server = false;  // poses sampled by the server from the uploaded clip
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

// The answers of one frame from every mesh's stream, gathered until the last arrives.
// Streams run one thread each; a stream that gets ahead of the slowest by more than
// `lead` frames waits before sending (answers waiting for their frame's other meshes stay
// bounded), unless the run stops.
class FrameGather {
 public:
  FrameGather(std::size_t meshes, uint64_t lead, const std::atomic<bool>* stop)
      : answered_(meshes, 0), lead_(lead), stop_(stop) {}

  // Blocks until `frame` may be sent: it is less than `lead` frames ahead of the slowest
  // mesh's answers (the slowest mesh itself never waits).
  void WaitToSend(uint64_t frame) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] {
      return *stop_ || frame < *std::min_element(answered_.begin(), answered_.end()) + lead_;
    });
  }

  // Adds mesh `mesh`'s answer; returns the whole frame once every mesh's answer is in.
  std::optional<std::vector<client::FrameResult>> Add(std::size_t mesh,
                                                      client::FrameResult result) {
    std::lock_guard lock(mutex_);
    ++answered_[mesh];
    changed_.notify_all();
    const uint64_t frame = result.frame;
    auto& parts = pending_[frame];
    if (parts.empty()) parts.resize(answered_.size());
    parts[mesh] = std::move(result);
    if (++arrived_[frame] < answered_.size()) return std::nullopt;
    std::vector<client::FrameResult> whole = std::move(pending_[frame]);
    pending_.erase(frame);
    arrived_.erase(frame);
    return whole;
  }

  // Wakes every waiting sender (after `stop` was set).
  void Stop() {
    { std::lock_guard lock(mutex_); }  // a waiter is asleep or has not yet seen `stop`
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<uint64_t> answered_;  // per mesh
  std::map<uint64_t, std::vector<client::FrameResult>> pending_;
  std::map<uint64_t, std::size_t> arrived_;
  uint64_t lead_;
  const std::atomic<bool>* stop_;
};

// The character and what is drawn of it: its meshes, the clip and how many frames of it.
struct Scene {
  Character character;
  std::vector<CharacterMesh> meshes;
  const AnimationClip* clip = nullptr;
  uint64_t frames = 0;
  std::optional<render::Camera> camera;  // --render
  // --on-server: each mesh's skeleton (MeshPalette's entries) and the clip on its joints.
  std::vector<Rig> rigs;
  std::vector<animation::RawClip> raw_clips;
  // Per mesh: the server applies the clip's weights tracks to its morph targets
  // (RawClipForMesh), so the client sends no weights.
  std::vector<bool> weights_on_server;

  // Frame i's palette for `mesh`: sampled as frames are sent (a long clip of a big skeleton
  // would not fit in memory).
  Result<std::vector<float>> Palette(uint64_t i, const CharacterMesh& mesh, double fps) const {
    return MeshPalette(character, SampleClip(character, *clip, i / fps), mesh);
  }
};

// --on-server: each mesh's rig and the clip's channels on it, before anything is uploaded.
Status BuildRigs(Scene* scene) {
  for (const CharacterMesh& mesh : scene->meshes) {
    auto rig = RigFromMesh(scene->character, mesh);
    if (!rig.ok()) {
      return Status(rig.status().code(),
                    fmt::format("--on-server: {}: {}", mesh.name, rig.status().message()));
    }
    bool on_server = false;
    scene->raw_clips.push_back(RawClipForMesh(*scene->clip, *rig, mesh, &on_server));
    scene->weights_on_server.push_back(on_server);
    scene->rigs.push_back(*std::move(rig));
  }
  return Status::Ok();
}

Result<std::unique_ptr<Scene>> LoadScene(const AnimateOptions& o) {
  auto scene = std::make_unique<Scene>();  // the clip points into its character: never moved
  auto character = ImportCharacter(o.file);
  if (!character.ok()) return character.status();
  scene->character = std::move(*character);
  if (o.primitive >= 0) {
    if (auto picked = PickPrimitive(scene->character, o.primitive, o.file); !picked.ok()) {
      return picked.status();
    }
  }
  auto built = CharacterMeshes(scene->character, o.primitive);
  if (!built.ok()) return built.status();
  scene->meshes = std::move(*built);
  auto clip = PickClip(scene->character, o.clip, o.file);
  if (!clip.ok()) return clip.status();
  scene->clip = *clip;
  // Frame i shows time i / fps; `seconds` of them, at least one.
  const double seconds = o.seconds > 0 ? o.seconds : scene->clip->duration;
  scene->frames = std::max<uint64_t>(1, std::llround(seconds * o.fps));
  // Frame 0 first, so that a palette error shows before anything is uploaded.
  for (const CharacterMesh& mesh : scene->meshes) {
    if (auto first = scene->Palette(0, mesh, o.fps); !first.ok()) return first.status();
  }
  if (o.on_server) {
    if (Status s = BuildRigs(scene.get()); !s.ok()) return s;
  }
  if (o.render) {
    const std::vector<Pose> poses =
        render::ClipPoses(scene->character, *scene->clip, o.fps, scene->frames);
    auto framing =
        render::CharacterCamera(scene->character, scene->meshes, poses, o.width, o.height);
    if (!framing.ok()) return framing.status();
    scene->camera = *framing;
  }
  return scene;
}

// One client per mesh (each remembers its mesh, to upload it again to a replica that
// lacks it), on one channel, and the mesh's id on the server.
struct MeshClient {
  std::unique_ptr<client::SkinClient> client;
  std::string mesh_id;
  std::string skeleton_id, clip_id;  // --on-server
};

Result<std::vector<MeshClient>> UploadMeshes(const CommonOptions& common, const Scene& scene,
                                             std::optional<RestEncoding> asked) {
  auto channel = common.Channel();
  if (!channel.ok()) return channel.status();
  std::vector<RestEncodingChoice> rest;
  for (const CharacterMesh& mesh : scene.meshes) {
    auto choice = MeshRestEncoding(scene.character, mesh, asked);
    if (!choice.ok()) return choice.status();
    rest.push_back(*std::move(choice));
  }
  std::vector<MeshClient> clients;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const CharacterMesh& mesh = scene.meshes[m];
    auto c = std::make_unique<client::SkinClient>(*channel, common.Limits());
    auto info = c->Upload(mesh.arrays, {.rest_encoding = rest[m].encoding});
    if (!info.ok()) {
      return Status(info.status().code(),
                    fmt::format("{}: {}", mesh.name, info.status().message()));
    }
    clients.push_back({std::move(c), info->mesh_id()});
    fmt::print("{}: {}  {} vertices, {} joints, {} triangles, {} primitive(s)\n", mesh.name,
               info->mesh_id(), info->vertex_count(), info->joint_count(), mesh.indices.size() / 3,
               mesh.parts.size());
    fmt::print("  rest stream {}: {}\n", RestEncodingName(rest[m].encoding), rest[m].reason);
  }
  return clients;
}

// --on-server: each mesh's skeleton and clip, uploaded once (the same content twice is
// stored once: meshes of one skin share them).
Status UploadRigs(const Scene& scene, std::vector<MeshClient>& clients) {
  for (std::size_t m = 0; m < clients.size(); ++m) {
    const std::string& name = scene.meshes[m].name;
    auto skeleton = clients[m].client->UploadSkeleton(scene.rigs[m].skeleton);
    if (!skeleton.ok()) {
      return Status(skeleton.status().code(),
                    fmt::format("{}: skeleton: {}", name, skeleton.status().message()));
    }
    auto clip = clients[m].client->UploadClip(scene.raw_clips[m], skeleton->skeleton_id());
    if (!clip.ok()) {
      return Status(clip.status().code(), fmt::format("{}: clip '{}': {}", name, scene.clip->name,
                                                      clip.status().message()));
    }
    clients[m].skeleton_id = skeleton->skeleton_id();
    clients[m].clip_id = clip->clip_id();
    fmt::print("  skeleton {}: {} joints, palette of {}\n", skeleton->skeleton_id(),
               skeleton->joint_count(), skeleton->palette_size());
    fmt::print("  clip {}: {} tracks, {} bytes stored ({} float bytes uploaded)\n", clip->clip_id(),
               clip->tracks(), clip->bytes(), clip->raw_bytes());
  }
  return Status::Ok();
}

// Streams every mesh's frames, one thread each, and writes each frame's files as its last
// answer arrives; the first failure (a palette's, a frame's or a file's) stops sending and
// is reported.
class AnimateRun {
 public:
  AnimateRun(const AnimateOptions& o, const Scene& scene)
      : o_(o),
        scene_(scene),
        progress_("animate", scene.frames),
        gather_(scene.meshes.size(), 2 * static_cast<uint64_t>(o.window), &stop_) {}

  // Streams and writes every frame; the error of the first mesh whose stream failed, else
  // the first failure.
  Status Run(std::vector<MeshClient>& clients) {
    const std::size_t meshes = scene_.meshes.size();
    summaries_.resize(meshes);
    std::vector<Status> streamed(meshes);
    const auto started = std::chrono::steady_clock::now();
    std::vector<std::thread> threads;
    for (std::size_t m = 0; m < meshes; ++m) {
      threads.emplace_back([&, m] { streamed[m] = StreamMesh(m, clients[m]); });
    }
    for (std::thread& t : threads) t.join();
    progress_.Finish();
    elapsed_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    for (std::size_t m = 0; m < meshes; ++m) {
      if (!streamed[m].ok()) {
        return Status(streamed[m].code(),
                      fmt::format("{}: {}", scene_.meshes[m].name, streamed[m].message()));
      }
    }
    return first_error_;
  }
  // After Run: whether every mesh had every frame answered.
  Status CheckAnswered() const {
    for (std::size_t m = 0; m < scene_.meshes.size(); ++m) {
      if (summaries_[m].answered != scene_.frames) {
        return Internal(fmt::format("{}: {} of {} frames answered", scene_.meshes[m].name,
                                    summaries_[m].answered, scene_.frames));
      }
    }
    return Status::Ok();
  }
  double elapsed() const { return elapsed_; }
  uint64_t written_obj() const { return written_obj_.load(); }
  uint64_t written_png() const { return written_png_.load(); }
  int64_t compute_ns() const { return compute_ns_.load(); }

 private:
  client::StreamOptions StreamOptionsOf(std::size_t m, const MeshClient& mesh_client);
  Status StreamMesh(std::size_t m, MeshClient& mesh_client);
  void Answered(std::size_t m, client::FrameResult& result);
  void WriteFrame(std::vector<client::FrameResult>& parts);
  void Fail(Status s) {
    {
      std::lock_guard lock(error_mutex_);
      if (first_error_.ok()) first_error_ = std::move(s);
    }
    stop_ = true;
    gather_.Stop();
  }

  const AnimateOptions& o_;
  const Scene& scene_;
  std::atomic<bool> stop_{false};
  std::mutex error_mutex_;
  Status first_error_;
  std::atomic<uint64_t> written_obj_{0}, written_png_{0};
  std::atomic<int64_t> compute_ns_{0};
  std::atomic<uint64_t> frames_done_{0};
  ProgressLine progress_;
  FrameGather gather_;
  std::vector<client::StreamSummary> summaries_;
  double elapsed_ = 0;
};

client::StreamOptions AnimateRun::StreamOptionsOf(std::size_t m, const MeshClient& mesh_client) {
  const CharacterMesh& mesh = scene_.meshes[m];
  return {.mesh_id = mesh_client.mesh_id,
          .backend = o_.backend,
          .want_normals = !mesh.arrays.normals.empty(),
          .method = o_.method,
          .frames = scene_.frames,
          .window = o_.window,
          .stop = &stop_};
}

Status AnimateRun::StreamMesh(std::size_t m, MeshClient& mesh_client) {
  const CharacterMesh& mesh = scene_.meshes[m];
  client::StreamOptions stream = StreamOptionsOf(m, mesh_client);
  // The mesh's morph target weights, sampled with the palette's pose; with --on-server
  // the server samples them from the clip's weights tracks, unless they do not give the
  // mesh's targets (RawClipForMesh).
  std::vector<MorphWeight> morph;
  if (!mesh.morph_sources.empty() && !(o_.on_server && scene_.weights_on_server[m])) {
    stream.morph_weights = [&](uint64_t f) {
      MeshMorphWeights(mesh, SampleClip(scene_.character, *scene_.clip, f / o_.fps), &morph);
      return std::span<const MorphWeight>(morph);
    };
  }
  // --on-server: frame f plays the clip at f / fps (clamped at its ends, as SampleClip).
  client::PoseLayer layer{.clip_id = mesh_client.clip_id};
  if (o_.on_server) {
    stream.pose = [&](uint64_t f) {
      gather_.WaitToSend(f);  // sent even after a stop: its answer is not written
      layer.time = static_cast<float>(static_cast<double>(f) / o_.fps);
      return client::Pose{.skeleton_id = mesh_client.skeleton_id, .layers = {&layer, 1}};
    };
  }
  return client::StreamFrames(
      *mesh_client.client, stream,
      [&](uint64_t f) {  // not asked for with --on-server
        gather_.WaitToSend(f);
        if (stop_) return std::vector<float>();  // never sent: the stream stops first
        auto palette = scene_.Palette(f, mesh, o_.fps);
        if (palette.ok()) return std::move(*palette);
        Fail(palette.status());  // the server rejects the empty palette; we stop sending
        return std::vector<float>();
      },
      [&](client::FrameResult& result, std::chrono::nanoseconds) { Answered(m, result); },
      &summaries_[m]);
}

void AnimateRun::Answered(std::size_t m, client::FrameResult& result) {
  if (!result.status.ok()) {
    return Fail(Status(result.status.code(), fmt::format("{}: frame {}: {}", scene_.meshes[m].name,
                                                         result.frame, result.status.message())));
  }
  compute_ns_ += static_cast<int64_t>(result.timing.compute_ns());
  auto whole = gather_.Add(m, std::move(result));
  if (whole && !stop_) {
    WriteFrame(*whole);
    progress_.Update(++frames_done_);
  }
}

void AnimateRun::WriteFrame(std::vector<client::FrameResult>& parts) {
  const uint64_t frame = parts.front().frame;
  std::vector<render::ObjMesh> obj;
  std::vector<render::RenderPart> render_parts;
  for (std::size_t m = 0; m < scene_.meshes.size(); ++m) {
    render::ObjMesh mesh{.positions = parts[m].positions,
                         .normals = parts[m].normals,
                         .indices = scene_.meshes[m].indices,
                         .groups = {}};
    for (const PrimitiveSpan& part : scene_.meshes[m].parts) {
      mesh.groups.push_back({part.name, part.first_index, part.index_count});
    }
    obj.push_back(std::move(mesh));
    render_parts.push_back({parts[m].positions, parts[m].normals, scene_.meshes[m].indices});
  }
  Status s = render::WriteObj(render::FrameFileName(o_.out, frame, "obj"), obj);
  if (!s.ok()) return Fail(s);
  ++written_obj_;
  if (!scene_.camera) return;
  // Unlabelled: the frames play as a sequence; the contact sheet labels its cells.
  s = render::RenderPng(render::FrameFileName(o_.out, frame, "png"), *scene_.camera, render_parts);
  if (!s.ok()) return Fail(s);
  ++written_png_;
}

// The contact sheet (with --render) and the run's summary line.
int FinishAnimate(const AnimateOptions& o, const Scene& scene, const AnimateRun& run) {
  std::string sheet_note;
  if (scene.camera) {
    std::vector<render::SheetFrame> sheet;
    for (std::size_t i :
         render::EvenlySpaced(scene.frames, static_cast<std::size_t>(o.sheet_frames))) {
      sheet.push_back({render::FrameFileName(o.out, i, "png"), FrameLabel(i, o.fps)});
    }
    const std::string path = o.out + "/contact-sheet.png";
    if (Status s = render::WriteContactSheet(path, sheet, o.sheet); !s.ok()) return Report(s);
    sheet_note =
        fmt::format(", {} PNG frames and {} ({} frames)", run.written_png(), path, sheet.size());
  }
  const uint64_t frames = scene.frames;
  fmt::print(
      "{} frames ({:.3f} s at {} fps), {} mesh(es) on {}{}: {:.2f} s, {:.1f} frames/s with files "
      "written, server compute {:.3f} ms/frame\nwrote {} OBJ frames{} in {}\n",
      frames, static_cast<double>(frames) / o.fps, o.fps, scene.meshes.size(),
      o.backend.empty() ? "the default backend" : o.backend,
      o.on_server ? ", poses sampled by the server" : "", run.elapsed(), frames / run.elapsed(),
      static_cast<double>(run.compute_ns()) / 1e6 / static_cast<double>(frames), run.written_obj(),
      sheet_note, o.out);
  return 0;
}

int Animate(const CommonOptions& common, const AnimateOptions& o) {
  if (Status s = CheckOptions(o); !s.ok()) return Report(s);
  auto asked = ParseRestEncodingOption(o.rest_encoding);
  if (!asked.ok()) return Report(asked.status());
  auto scene = LoadScene(o);
  if (!scene.ok()) return Report(scene.status());
  std::error_code error;
  std::filesystem::create_directories(o.out, error);
  if (error) {
    return Report(Internal(fmt::format("--out {}: cannot create: {}", o.out, error.message())));
  }
  auto clients = UploadMeshes(common, **scene, *asked);
  if (!clients.ok()) return Report(clients.status());
  if (o.on_server) {
    if (Status s = UploadRigs(**scene, *clients); !s.ok()) return Report(s);
  }
  fmt::print("clip '{}' ({:.3f} s)\n", (*scene)->clip->name, (*scene)->clip->duration);
  AnimateRun run(o, **scene);
  if (Status s = run.Run(*clients); !s.ok()) return Report(s);
  if (Status s = run.CheckAnswered(); !s.ok()) return Report(s);
  return FinishAnimate(o, **scene, run);
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
  AddRestEncodingOption(command, &o->rest_encoding);
  AddMethodOption(command, &o->method);
  command->add_option("--out", o->out, "output directory (created if missing)")->required();
  command->add_flag("--render", o->render,
                    "also draw each frame as PNG (Cairo, fixed camera) and a contact sheet");
  command->add_option("--width", o->width, "PNG width")->capture_default_str();
  command->add_option("--height", o->height, "PNG height")->capture_default_str();
  command->add_option(
      "--primitive", o->primitive,
      "only this primitive, skinned or rigid (default: every one, the whole character)");
  command->add_option("--window", o->window, "frames in flight")->capture_default_str();
  command
      ->add_option("--sheet-frames", o->sheet_frames, "frames on the contact sheet, evenly spaced")
      ->capture_default_str();
  command->add_option("--sheet-columns", o->sheet.columns, "contact sheet columns")
      ->capture_default_str();
  command->add_option("--sheet-width", o->sheet.width, "contact sheet width in pixels")
      ->capture_default_str();
  command->add_flag("--on-server", o->on_server,
                    "upload each mesh's skeleton and the clip once; frames carry the clip time and "
                    "the server samples the pose (docs/serving/animation.md)");
  command->callback([&common, o] { common.exit_code = Animate(common, *o); });
}

}  // namespace skinserve::cli
