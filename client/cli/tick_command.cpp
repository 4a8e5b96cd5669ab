// skinserve-cli tick: one tick (SkinRequest.characters) of several characters: synthetic
// meshes, the meshes of glTF characters and meshes already on the server, each with its own
// palette, skinned by one request. Prints each character's outcome: its vertices, timing and
// error against the float64 reference (for the meshes it has locally), or its error; the
// exit status is 1 when any character failed or disagreed with its reference. With
// --frame-socket the tick goes over the server's frame socket instead of gRPC (uploads and
// the region's registration stay on gRPC).
#include <fmt/format.h>

#include <memory>
#include <string>
#include <vector>

#include "character_input.h"
#include "commands.h"
#include "rest_encoding_option.h"
#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/client/frame_socket_client.h"
#include "skinserve/client/tick.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::cli {
namespace {

struct TickOptions {
  MeshOptionsCli mesh;  // the synthetic meshes' shape
  int synthetic = -1;   // -1: 3 when no file and no --mesh-id names a character
  std::vector<std::string> files;
  std::vector<std::string> mesh_ids;  // meshes on the server (upload); unknown: NOT_FOUND
  std::string clip;                   // glTF: the clip sampled (default: the first)
  double time = 0;                    // glTF: seconds into the clip
  std::string backend;
  uint64_t frame = 0;  // the tick's number; synthetic palettes' pose
  SkinningMethod method = SkinningMethod::kLinear;
  bool shared_memory = false;
  std::string shm_dir = "/dev/shm";
  std::string frame_socket;  // the server's --frame-socket: the tick goes there
};

// One character of the tick: where it comes from, its mesh and what it sends; `local` (the
// mesh as the server stores it) when this command has the mesh, for the reference check.
struct CharacterInput {
  std::string label;
  std::string mesh_id;
  std::shared_ptr<const Mesh> local;
  std::vector<float> palette;
  std::vector<MorphWeight> morph;
  uint32_t vertices = 0;
  bool normals = false, tangents = false;
};

Status AddSynthetic(client::SkinClient& client, const TickOptions& o, int count,
                    std::vector<CharacterInput>* out) {
  for (int i = 0; i < count; ++i) {
    SyntheticMeshSpec spec = o.mesh.spec;
    spec.seed += static_cast<uint64_t>(i);  // distinct meshes
    const MeshArrays arrays = MakeSyntheticMesh(spec);
    auto info = client.Upload(arrays);
    if (!info.ok()) return info.status();
    auto local = Mesh::Create(arrays);
    if (!local.ok()) return local.status();
    out->push_back({.label = fmt::format("synthetic seed {}", spec.seed),
                    .mesh_id = info->mesh_id(),
                    .local = *local,
                    .palette = o.method == SkinningMethod::kDualQuaternion
                                   ? MakeRigidPalette(arrays.joint_count, spec.seed, o.frame)
                                   : MakeSyntheticPalette(arrays.joint_count, spec.seed, o.frame),
                    .vertices = spec.vertex_count,
                    .normals = spec.normals,
                    .tangents = spec.tangents});
  }
  return Status::Ok();
}

// Every mesh of the glTF character at `path` (one per skin, as upload makes them), posed at
// --time of --clip (the rest pose when the file has no clip and none is named).
Status AddCharacterFile(client::SkinClient& client, const TickOptions& o, const std::string& path,
                        std::vector<CharacterInput>* out) {
  if (!IsGltfPath(path)) return InvalidArgument(fmt::format("{}: not a .glb or .gltf file", path));
  auto character = ImportCharacter(path);
  if (!character.ok()) return character.status();
  auto meshes = CharacterMeshes(*character);
  if (!meshes.ok()) return meshes.status();
  Pose pose = RestPose(*character);
  if (!o.clip.empty() || !character->clips.empty()) {
    auto clip = PickClip(*character, o.clip, path);
    if (!clip.ok()) return clip.status();
    pose = SampleClip(*character, **clip, o.time);
  }
  for (const CharacterMesh& mesh : *meshes) {
    auto rest = MeshRestEncoding(*character, mesh, std::nullopt);
    if (!rest.ok()) return rest.status();
    auto info = client.Upload(mesh.arrays, {.rest_encoding = rest->encoding});
    if (!info.ok()) {
      return Status(info.status().code(),
                    fmt::format("{} {}: {}", path, mesh.name, info.status().message()));
    }
    auto local = Mesh::Create(mesh.arrays, {.rest_encoding = rest->encoding});
    if (!local.ok()) return local.status();
    auto palette = MeshPalette(*character, pose, mesh);
    if (!palette.ok()) return palette.status();
    CharacterInput input{.label = fmt::format("{} {}", path, mesh.name),
                         .mesh_id = info->mesh_id(),
                         .local = *local,
                         .palette = *std::move(palette),
                         .vertices = (*local)->vertex_count(),
                         .normals = (*local)->has_normals()};
    MeshMorphWeights(mesh, pose, &input.morph);
    out->push_back(std::move(input));
  }
  return Status::Ok();
}

// A mesh already on the server: posed with the synthetic palette of its joint count. One the
// server does not know still goes into the tick (with a one-joint palette), so that the
// server's answer names it.
void AddMeshId(client::SkinClient& client, const TickOptions& o, const std::string& id,
               std::vector<CharacterInput>* out) {
  auto info = client.GetMesh(id);
  const uint32_t joints = info.ok() ? info->joint_count() : 1;
  out->push_back({.label = fmt::format("mesh {}", id),
                  .mesh_id = id,
                  .palette = MakeSyntheticPalette(joints, o.mesh.spec.seed, o.frame),
                  .vertices = info.ok() ? info->vertex_count() : 1,
                  .normals = info.ok() && info->has_normals()});
}

Result<std::vector<CharacterInput>> GatherCharacters(client::SkinClient& client,
                                                     const TickOptions& o) {
  std::vector<CharacterInput> inputs;
  const int synthetic =
      o.synthetic >= 0 ? o.synthetic : (o.files.empty() && o.mesh_ids.empty() ? 3 : 0);
  if (Status s = AddSynthetic(client, o, synthetic, &inputs); !s.ok()) return s;
  for (const std::string& path : o.files) {
    if (Status s = AddCharacterFile(client, o, path, &inputs); !s.ok()) return s;
  }
  for (const std::string& id : o.mesh_ids) AddMeshId(client, o, id, &inputs);
  if (inputs.empty()) {
    return InvalidArgument("tick: no character: give FILEs, --mesh-id or --synthetic N >= 1");
  }
  return inputs;
}

// Prints character i's outcome; false when it failed or disagreed with its reference.
bool PrintCharacter(std::size_t i, const CharacterInput& input, client::FrameResult& result,
                    SkinningMethod method) {
  if (!result.status.ok()) {
    fmt::print("character {} ({}): {}\n", i, input.label, result.status.ToString());
    return false;
  }
  if (result.in_region()) {
    if (Status s = client::DecodeRegionFrame(&result); !s.ok()) {
      fmt::print("character {} ({}): {}\n", i, input.label, s.ToString());
      return false;
    }
  }
  const std::size_t vertices = result.positions.size() / 3;
  std::string check = "not checked (no local copy of the mesh)";
  bool ok = true;
  if (input.local != nullptr && vertices != input.local->vertex_count()) {
    ok = false;
    check = fmt::format("MISMATCH: {} vertices expected", input.local->vertex_count());
  } else if (input.local != nullptr) {
    const Deviation d = CompareWithReference(*input.local, input.palette, result.positions,
                                             result.normals, method, input.morph, result.tangents);
    ok = d.within_tolerance();
    check = fmt::format("max error vs float64 reference {:.3g} (tolerance {:.3g}){}",
                        d.max_position_error, d.position_tolerance, ok ? "" : " MISMATCH");
  }
  fmt::print("character {} ({}): {} vertices{}, queued {:.3f} ms, compute {:.3f} ms; {}\n", i,
             input.label, vertices, result.in_region() ? " in the region" : "",
             result.timing.queued_ns() / 1e6, result.timing.compute_ns() / 1e6, check);
  return ok;
}

// The tick over the frame socket at `path`: its answer read as StreamSkin's, into `result`.
Status SkinTickOnFrameSocket(const std::string& path, const client::Tick& tick,
                             client::TickResult* result) {
  auto socket = client::FrameSocketClient::Connect(path);
  if (!socket.ok()) return socket.status();
  v1::SkinRequest request;
  tick.ToWire(&request);
  grpc::ByteBuffer part;
  if (!(*socket)->Write(request)) {
    while ((*socket)->Read(&part)) {
    }
    return (*socket)->Finish();  // the server's reason for ending the connection
  }
  client::TickAssembler assembler(tick, result);
  client::RawPart reader;
  while ((*socket)->Read(&part)) {
    if (assembler.Add(part, &reader)) {
      (*socket)->WritesDone();
      return result->status;
    }
  }
  return (*socket)->Finish();
}

int RunTick(const CommonOptions& common, const TickOptions& o) {
  auto channel = common.Channel();
  if (!channel.ok()) return Report(channel.status());
  client::SkinClient client(*channel, common.Limits());
  auto inputs = GatherCharacters(client, o);
  if (!inputs.ok()) return Report(inputs.status());
  // Shared memory: each character its own range of one region, one after another.
  std::vector<uint64_t> offsets;
  uint64_t region_bytes = 0;
  for (const CharacterInput& input : *inputs) {
    offsets.push_back(region_bytes);
    region_bytes += wire::RegionFrameBytes(input.vertices, 1, VertexEncoding::kFloat32,
                                           input.normals, input.tangents);
  }
  std::unique_ptr<client::SharedMemoryRegion> region;
  const std::string region_name = client::SharedMemoryRegion::UniqueKey("cli-tick");
  if (o.shared_memory) {
    auto made = client::SharedMemoryRegion::Create(region_name, region_bytes, o.shm_dir);
    if (!made.ok()) return Report(made.status());
    region = std::move(made).value();
    if (auto registered = client.RegisterRegion(region_name, *region); !registered.ok()) {
      return Report(registered.status());
    }
  }
  client::Tick tick;
  tick.set_frame(o.frame);
  for (std::size_t i = 0; i < inputs->size(); ++i) {
    const CharacterInput& input = (*inputs)[i];
    client::SkinOptions options{.backend = o.backend,
                                .want_normals = input.normals,
                                .want_tangents = input.tangents,
                                .method = o.method,
                                .morph_weights = input.morph};
    if (region != nullptr) options.output = {region_name, region.get(), offsets[i]};
    tick.Add(input.mesh_id, input.palette, options);
  }
  client::TickResult result;
  const Status status = o.frame_socket.empty()
                            ? client.SkinTick(tick, &result)
                            : SkinTickOnFrameSocket(o.frame_socket, tick, &result);
  int code = status.ok() ? 0 : Report(status);
  std::size_t failed = 0;
  for (std::size_t i = 0; status.ok() && i < inputs->size(); ++i) {
    if (i >= result.characters.size()) {
      fmt::print("character {} ({}): no answer\n", i, (*inputs)[i].label);
      ++failed;
    } else if (!PrintCharacter(i, (*inputs)[i], result.characters[i], o.method)) {
      ++failed;
    }
  }
  if (region != nullptr) {
    if (Status u = client.UnregisterRegion(region_name); !u.ok() && code == 0) code = Report(u);
  }
  if (status.ok()) {
    fmt::print("tick {}: {} characters, {} answered, {} failed\n", o.frame, inputs->size(),
               inputs->size() - failed, failed);
  }
  return failed > 0 ? 1 : code;
}

}  // namespace

void AddTickCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "tick",
      "skin one tick: several characters (synthetic meshes, glTF characters, meshes on the "
      "server) in one request; prints each character's outcome, exit status 1 when any failed");
  auto o = std::make_shared<TickOptions>();
  o->mesh.Add(command);
  command
      ->add_option("--synthetic", o->synthetic,
                   "this many distinct synthetic meshes (seeds --seed, --seed + 1, ...) of "
                   "the synthetic mesh options (default: 3 when no FILE and no --mesh-id)")
      ->check(CLI::Range(0, 4096));
  command->add_option("files", o->files,
                      "glTF 2.0 characters: each of their meshes (one per skin) is a character");
  command
      ->add_option("--mesh-id", o->mesh_ids,
                   "a mesh already on the server (skinserve-cli upload), posed with the "
                   "synthetic palette of its joint count; repeat for more")
      ->allow_extra_args(false);
  command->add_option("--clip", o->clip, "glTF: the clip to pose (default: the first)");
  command->add_option("--time", o->time, "glTF: seconds into the clip")->capture_default_str();
  command->add_option("--backend", o->backend,
                      "backend id of every character (default: the server's)");
  command->add_option("--frame", o->frame, "the tick's number (selects the synthetic poses)")
      ->capture_default_str();
  AddMethodOption(command, &o->method);
  command->add_flag("--shared-memory", o->shared_memory,
                    "have the server write each character into its own range of a "
                    "shared-memory region this command creates (the server must run on this host)");
  command->add_option("--shm-dir", o->shm_dir, "the server's --shm-dir, where the region is made")
      ->capture_default_str();
  command->add_option("--frame-socket", o->frame_socket,
                      "send the tick over the server's frame socket at this path (skinserve "
                      "--frame-socket, same host) instead of gRPC; with --shared-memory the "
                      "--target must be the server's unix: address (the region's owner)");
  command->callback([&common, o] { common.exit_code = RunTick(common, *o); });
}

}  // namespace skinserve::cli
