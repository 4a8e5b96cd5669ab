// skinserve-gpu-region: a headless Vulkan renderer's side of GPU regions
// (docs/serving/gpu-regions.md). It allocates a vertex buffer on the GPU, exports it as an
// opaque fd, hands the fd to the server (--fd-socket) and registers it (GpuRegions), then
// streams a character's palettes with every frame written into the buffer by the server's
// `opencl` backend: the synthetic one (random palettes, no faces: drawn as points), or with
// --mesh a glTF character loaded as skinserve-load --mesh loads it (every primitive of the
// file as one mesh, its first clip sampled every 1/30 s, looping; drawn as triangles). --check and
// --draw use a buffer of one frame registered with an exported semaphore (unless --semaphore
// false), which the server signals once per answered frame: each frame's GPU work waits on it
// (window 1, so the wait has run before the next frame is sent). --check copies each frame back and
// compares it with the float64 reference; --draw draws the character mid-walk from the buffer
// (vertex_renderer.h) into a PNG and checks the picture against the reference (draw_check.h,
// triangle_check.h). The speed run streams --frames frames with --window in flight into a buffer
// without a semaphore, then the same frames into a shared-memory region (read back from the GPU
// into host memory), then the same again on --compare-backend (simd-openmp: the server's CPUs) into
// shared memory. --encoding float16 or snorm16: every frame of those runs and checks in that
// encoding, written encoded into the GPU buffer by the server (decoded by --check; --draw
// draws float32 vertices). --characters-per-tick N: each frame a tick of N characters (the
// synthetic one on N meshes of its own, seeds 7 to 7 + N - 1; a --mesh character N times),
// all into the region, which the server signals once per tick; --check checks every
// character. --rate R: a paced run after the speed run, --frames frames at R a second into
// the GPU region (window 1), with its latencies and the frames answered later than a period
// after their send: N clients at --rate 60 are N streams held at 60 ticks/s, or not.
// Prints one summary line per run and PASS or FAIL.
#include <fmt/format.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <thread>

#include "frame_streams.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/gpu_fd_handoff.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/region_layout.h"
#include "vulkan_device.h"
#include "workload.h"  // client/load: MakeGltfWorkload, as skinserve-load --mesh
#if SKINSERVE_GPU_REGION_DRAW
#include "draw_check.h"
#include "host_buffer.h"
#include "png_file.h"
#include "vertex_renderer.h"
#endif

namespace skinserve::gpu_region {
namespace {

struct Options {
  std::string target, fd_socket, backend = "opencl", shm_dir = "/dev/shm";
  std::string mesh_path;                        // --mesh: a glTF character ("" synthetic)
  std::string compare_backend = "simd-openmp";  // the speed run's CPU row ("" none)
  uint32_t vertices = 25000, influences = 2, frames = 600, window = 2, check_frames = 0;
  double rate = 0;          // --rate: a paced run instead of the speed runs
  double start_at = 0;      // --start-at: when the paced run starts (Unix seconds; 0: at once)
  uint32_t characters = 1;  // --characters-per-tick (1: plain frames)
  bool normals = false, compare_shm = true, semaphore = true;
  int vulkan_device = -1;
  std::string draw_path;  // --draw: the picture's PNG ("" none)
  uint32_t draw_size = 768;
  VertexEncoding encoding = VertexEncoding::kFloat32;
};

struct Session {
  Options options;
  std::shared_ptr<const Mesh> mesh;                 // character 0's
  std::vector<std::shared_ptr<const Mesh>> meshes;  // character c's (ticks)
  std::vector<std::string> mesh_ids;
  // The character's distinct poses, frame f taking f % size: the synthetic walk's, or the
  // glTF clip's every 1/30 s (with their morph weights, when it has morph targets).
  std::vector<std::string> palettes;
  std::vector<std::vector<MorphWeight>> morph;
  std::vector<uint32_t> indices;  // triangles (a glTF character's), empty: points
  uint64_t slot_bytes = 0;
  std::unique_ptr<client::SkinClient> client;
  std::unique_ptr<v1::GpuRegions::Stub> gpu;
};

constexpr uint32_t kSyntheticPoses = 64;

std::string PaletteBytes(std::span<const float> palette) {
  return {reinterpret_cast<const char*>(palette.data()), palette.size() * sizeof(float)};
}

// The synthetic character of --vertices x --influences, and its walk's poses.
Result<std::shared_ptr<const MeshArrays>> SyntheticCharacter(Session& s) {
  auto arrays =
      std::make_shared<const MeshArrays>(MakeSyntheticMesh({.vertex_count = s.options.vertices,
                                                            .influences = s.options.influences,
                                                            .normals = s.options.normals,
                                                            .seed = 7}));
  for (uint32_t f = 0; f < kSyntheticPoses; ++f) {
    s.palettes.push_back(PaletteBytes(MakeSyntheticPalette(arrays->joint_count, 3, f)));
  }
  auto mesh = Mesh::Create(*arrays);
  if (!mesh.ok()) return mesh.status();
  s.mesh = *mesh;
  return arrays;
}

// Character c (> 0) of a tick: the synthetic character of its own seed, uploaded.
Status UploadTickCharacter(Session& s, uint32_t c) {
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = s.options.vertices,
                                               .influences = s.options.influences,
                                               .normals = s.options.normals,
                                               .seed = 7 + c});
  auto mesh = Mesh::Create(arrays);
  if (!mesh.ok()) return mesh.status();
  auto info = s.client->Upload(arrays);
  if (!info.ok()) return info.status();
  s.meshes.push_back(*mesh);
  s.mesh_ids.push_back(info->mesh_id());
  return Status::Ok();
}

// --mesh: the glTF character as skinserve-load --mesh loads it (MakeGltfWorkload: every
// primitive, skinned or rigid, in one mesh; its first clip every 1/30 s), skinned with
// normals whenever it has them (the picture is shaded by them).
Result<std::shared_ptr<const MeshArrays>> GltfCharacter(Session& s) {
  auto w = load::MakeGltfWorkload(s.options.mesh_path, -1, s.options.normals);
  if (!w.ok()) return w.status();
  s.options.vertices = w->vertices;
  s.options.influences = w->bones;
  s.options.normals = !w->arrays->normals.empty();
  s.mesh = w->mesh;
  for (const std::vector<float>& palette : w->palettes) s.palettes.push_back(PaletteBytes(palette));
  s.morph = std::move(w->morph_weights);
  s.indices = w->indices;
  fmt::print(
      "character: {}: {} vertices, {} triangles, {} joints (all of its primitives in one mesh, as "
      "skinserve-load --mesh uploads it), {} normals; {} poses of its first clip at 1/30 s{}\n",
      s.options.mesh_path, w->vertices, w->indices.size() / 3, w->joints,
      s.options.normals ? "with" : "without", s.palettes.size(),
      s.morph.empty() ? "" : ", with their morph target weights");
  return w->arrays;
}

Status Prepare(Session& s) {
  auto arrays = s.options.mesh_path.empty() ? SyntheticCharacter(s) : GltfCharacter(s);
  if (!arrays.ok()) return arrays.status();
  auto channel = client::MakeChannel(s.options.target);
  s.client = std::make_unique<client::SkinClient>(channel);
  s.gpu = v1::GpuRegions::NewStub(channel);
  auto info = s.client->Upload(**arrays);
  if (!info.ok()) return info.status();
  s.meshes = {s.mesh};
  s.mesh_ids = {info->mesh_id()};
  for (uint32_t c = 1; c < s.options.characters; ++c) {
    if (!s.options.mesh_path.empty()) {  // the glTF character again
      s.meshes.push_back(s.mesh);
      s.mesh_ids.push_back(s.mesh_ids[0]);
    } else if (Status st = UploadTickCharacter(s, c); !st.ok()) {
      return st;
    }
  }
  const wire::RegionLayout layout =
      wire::LayoutInRegion(0, s.options.vertices, 1, s.options.encoding, s.options.normals);
  s.slot_bytes = wire::RoundUpToRegionAlignment(layout.end_offset);
  return Status::Ok();
}

// An fd handed over the server's --gpu-fd-socket: its token (the fd is closed here).
Result<std::string> HandOver(const Session& s, Result<int> fd) {
  if (!fd.ok()) return fd.status();
  Result<std::string> token = client::HandOverGpuFd(s.options.fd_socket, *fd);
  close(*fd);  // the server has its own
  return token;
}

// Registers `buffer` as GPU region `name`, with `semaphore` (null: none) for the server
// to signal once per answered frame.
Status RegisterGpu(Session& s, const VulkanDevice& device, const ExportedBuffer& buffer,
                   const std::string& name, const ExportedSemaphore* semaphore = nullptr) {
  Result<std::string> token = HandOver(s, buffer.ExportFd());
  if (!token.ok()) return token.status();
  v1::RegisterGpuRegionRequest request;
  if (semaphore != nullptr) {
    Result<std::string> semaphore_token = HandOver(s, semaphore->ExportFd());
    if (!semaphore_token.ok()) return semaphore_token.status();
    request.set_semaphore_fd_token(*semaphore_token);
  }
  request.set_name(name);
  request.set_fd_token(*token);
  request.set_byte_size(buffer.allocation_bytes());
  request.set_device_uuid(std::string(reinterpret_cast<const char*>(device.uuid().data()), 16));
  request.set_backend(s.options.backend);
  grpc::ClientContext context;
  v1::GpuRegionInfo info;
  if (Status st = wire::FromGrpc(s.gpu->RegisterGpuRegion(&context, request, &info)); !st.ok()) {
    return st;
  }
  if (info.signals_semaphore() != (semaphore != nullptr)) {
    return Internal(fmt::format("GPU region '{}': signals_semaphore = {}, registered {}", name,
                                info.signals_semaphore(),
                                semaphore != nullptr ? "with a semaphore" : "without one"));
  }
  return Status::Ok();
}

// `run`'s status when it failed (a failed `cleanup` printed beside it, not lost), else
// `cleanup`'s.
Status AfterCleanup(Status run, Status cleanup) {
  if (run.ok()) return cleanup;
  if (!cleanup.ok()) fmt::print(stderr, "also: {}\n", cleanup.ToString());
  return run;
}

// `run`'s status, after unregistering GPU region `name` whatever it was: a run that failed
// leaves no region behind either (the server would hold it, and its device memory, until
// idle).
Status UnregisterGpuAfter(Session& s, const std::string& name, Status run) {
  v1::UnregisterGpuRegionRequest request;
  request.set_name(name);
  grpc::ClientContext context;
  v1::UnregisterGpuRegionResponse response;
  Status st = wire::FromGrpc(s.gpu->UnregisterGpuRegion(&context, request, &response));
  if (!st.ok()) {
    st = Status(st.code(), fmt::format("unregistering GPU region '{}': {}", name, st.message()));
  }
  return AfterCleanup(std::move(run), std::move(st));
}

// Character c's pose in frame f: the walk's (or clip's) pose f + c.
const std::string& PaletteBytesOf(const Session& s, uint32_t frame, uint32_t c = 0) {
  return s.palettes[(frame + c) % s.palettes.size()];
}

std::span<const float> Palette(const Session& s, uint32_t frame, uint32_t c = 0) {
  const std::string& p = PaletteBytesOf(s, frame, c);
  return {reinterpret_cast<const float*>(p.data()), p.size() / sizeof(float)};
}

std::span<const MorphWeight> Morph(const Session& s, uint32_t frame, uint32_t c = 0) {
  if (s.morph.empty()) return {};
  return s.morph[(frame + c) % s.morph.size()];
}

StreamPlan Plan(const Session& s, const std::string& region, bool gpu, uint32_t frames,
                uint32_t window, const std::string& backend = "") {
  return {.mesh_ids = s.mesh_ids,
          .backend = backend.empty() ? s.options.backend : backend,
          .region = region,
          .gpu = gpu,
          .frames = frames,
          .window = window,
          .slot_bytes = s.slot_bytes,
          .normals = s.options.normals,
          .encoding = s.options.encoding,
          .palette = [&s](uint32_t f, uint32_t c) -> const std::string& {
            return PaletteBytesOf(s, f, c);
          },
          .morph = [&s](uint32_t f, uint32_t c) { return Morph(s, f, c); }};
}

// The one-frame GPU region --check and --draw write into, with its semaphore (null when
// --semaphore false): each answered frame's GPU work waits on it once.
struct WaitedRegion {
  std::string name = "waited";
  std::unique_ptr<ExportedBuffer> buffer;
  std::unique_ptr<ExportedSemaphore> semaphore;
  VkSemaphore wait() const {
    return semaphore != nullptr ? semaphore->semaphore() : VK_NULL_HANDLE;
  }
};

// A frame's room in a region: one slot per character.
uint64_t TickBytes(const Session& s) { return s.slot_bytes * s.options.characters; }

Result<WaitedRegion> RegisterWaited(Session& s, const VulkanDevice& device) {
  WaitedRegion r;
  auto buffer = ExportedBuffer::Create(device, TickBytes(s));
  if (!buffer.ok()) return buffer.status();
  r.buffer = std::move(buffer).value();
  if (s.options.semaphore) {
    auto semaphore = ExportedSemaphore::Create(device);
    if (!semaphore.ok()) return semaphore.status();
    r.semaphore = std::move(semaphore).value();
  }
  if (Status st = RegisterGpu(s, device, *r.buffer, r.name, r.semaphore.get()); !st.ok()) {
    return st;
  }
  return r;
}

// Character c's answer in a frame copied back from the GPU (`base`: the slot's bytes,
// `header`: its RegionWrite and box), decoded (float32: as it is) and compared with the
// float64 reference of its mesh and pose, within float32's tolerance plus the encoding's
// bound.
Status CheckCharacter(const Session& s, uint32_t frame, uint32_t c, const v1::SkinResponse& header,
                      const std::byte* base, double* worst) {
  const VertexEncoding encoding = s.options.encoding;
  const uint32_t v = s.options.vertices;
  const v1::RegionWrite& w = header.region_write();
  const std::size_t bytes = EncodedBytes(encoding, v);
  const Bounds box = header.has_bounds() ? wire::FromWire(header.bounds()) : Bounds{};
  std::vector<float> positions(3ull * v), normals(s.options.normals ? 3ull * v : 0);
  if (Status st = DecodePositions(encoding, {base + w.positions_offset(), bytes}, box, positions);
      !st.ok()) {
    return st;
  }
  if (s.options.normals) {
    if (Status st = DecodeNormals(encoding, {base + w.normals_offset(), bytes}, normals);
        !st.ok()) {
      return st;
    }
  }
  const EncodedDeviation d =
      CompareEncodedWithReference(*s.meshes[c], Palette(s, frame, c), encoding, box, positions,
                                  normals, SkinningMethod::kLinear, Morph(s, frame, c));
  *worst = std::max(*worst, d.max_position_error);
  if (d.within_tolerance()) return Status::Ok();
  return Internal(fmt::format(
      "frame {} character {} ({}): values beyond float32's tolerance plus the encoding's "
      "bound: position ratio {:.3g} (error {:.3g}), normal ratio {:.3g} at vertex {}",
      frame, c, VertexEncodingName(encoding), d.worst_position_ratio, d.max_position_error,
      d.worst_normal_ratio, d.worst_vertex));
}

// Window 1: each frame (or tick) copied back from the GPU (after waiting on the semaphore
// there) and every character of it compared with the reference.
Status Check(Session& s, const WaitedRegion& region, ReadBack& read_back, uint32_t* checked,
             double* worst) {
  const uint32_t characters = s.options.characters;
  return StreamIntoRegion(
      s.client->stub(), Plan(s, region.name, true, s.options.check_frames, 1),
      [&](uint32_t frame, const v1::SkinResponse& response) -> Status {
        Result<const void*> bytes = read_back.Copy(*region.buffer, 0, TickBytes(s), region.wait());
        if (!bytes.ok()) return bytes.status();
        const auto* base = static_cast<const std::byte*>(*bytes);
        if (characters == 1) {
          if (Status st = CheckCharacter(s, frame, 0, response, base, worst); !st.ok()) return st;
        } else {
          if (response.tick().characters_size() != static_cast<int>(characters)) {
            return Internal(fmt::format("frame {}: the tick's answer has {} characters, not {}",
                                        frame, response.tick().characters_size(), characters));
          }
          for (const v1::SkinResponse& header : response.tick().characters()) {
            if (Status st = CheckCharacter(s, frame, header.character(), header, base, worst);
                !st.ok()) {
              return st;
            }
          }
        }
        ++*checked;
        return Status::Ok();
      });
}

#if SKINSERVE_GPU_REGION_DRAW
// The float64 reference of frame `f` and the front view framed on its bounds.
struct DrawnPose {
  ReferenceFrame reference;
  Transform transform;
};

DrawnPose ReferencePose(const Session& s, uint32_t f, uint32_t size) {
  DrawnPose pose{.reference = ReferenceSkin(*s.mesh, Palette(s, f), Morph(s, f))};
  pose.transform = FrontViewOf(pose.reference.positions, size, size);
  return pose;
}

// The character's triangles in an index buffer (none for the synthetic one: points).
Result<std::unique_ptr<HostBuffer>> IndexBuffer(const Session& s, const VulkanDevice& device) {
  if (s.indices.empty()) return std::unique_ptr<HostBuffer>();
  return HostBuffer::Create(device, s.indices.data(), s.indices.size() * sizeof(uint32_t),
                            VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
}

// --draw: frames 0 to the middle pose (the synthetic walk's, or the clip's), each drawn
// from the GPU region by a submission that waits on the semaphore; the last one's picture
// checked against the reference and written as a PNG.
Status Draw(Session& s, const VulkanDevice& device, const WaitedRegion& region) {
  const uint32_t size = s.options.draw_size;
  const auto last = static_cast<uint32_t>(s.palettes.size() / 2);
  auto renderer = VertexRenderer::Create(device, size, size);
  if (!renderer.ok()) return renderer.status();
  auto indices = IndexBuffer(s, device);
  if (!indices.ok()) return indices.status();
  const DrawnPose pose = ReferencePose(s, last, size);
  std::span<const uint8_t> pixels;
  const auto draw = [&](uint32_t frame, const v1::SkinResponse& response) -> Status {
    const v1::RegionWrite& w = response.region_write();
    auto drawn =
        (*renderer)->Draw({.vertices = region.buffer->buffer(),
                           .positions_offset = w.positions_offset(),
                           .normals_offset = w.normals_offset(),
                           .normals = s.options.normals,
                           .vertex_count = s.options.vertices,
                           .indices = *indices != nullptr ? (*indices)->buffer() : VK_NULL_HANDLE,
                           .index_count = static_cast<uint32_t>(s.indices.size()),
                           .external = true,
                           .wait = region.wait(),
                           .transform = pose.transform});
    if (!drawn.ok()) return drawn.status();
    if (frame == last) pixels = *drawn;
    return Status::Ok();
  };
  Status streamed =
      StreamIntoRegion(s.client->stub(), Plan(s, region.name, true, last + 1, 1), draw);
  if (!streamed.ok()) return streamed;
  const PictureVerdict verdict = JudgePicture(pixels, size, size, pose.reference.positions,
                                              pose.reference.normals, s.indices, pose.transform);
  if (Status st = WritePng(s.options.draw_path, pixels, size, size); !st.ok()) return st;
  fmt::print("draw: frame {} ({}) drawn from the GPU region as {} into {} ({} x {}): {}\n", last,
             s.indices.empty() ? "the synthetic walk's middle pose"
                               : fmt::format("the clip's middle, {:.3f} s", last / 30.0),
             s.indices.empty() ? "points" : "triangles", s.options.draw_path, size, size,
             verdict.summary);
  if (!verdict.ok) return Internal("the picture does not show the reference");
  return Status::Ok();
}
#endif

// frames/s of `frames` frames into `region` with the window in flight, on `backend`
// ("": --backend).
Result<double> Speed(Session& s, const std::string& region, bool gpu,
                     const std::string& backend = "") {
  const auto started = std::chrono::steady_clock::now();
  Status status = StreamIntoRegion(
      s.client->stub(), Plan(s, region, gpu, s.options.frames, s.options.window, backend),
      [](uint32_t, const v1::SkinResponse&) { return Status::Ok(); });
  if (!status.ok()) return status;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return s.options.frames / seconds;
}

// --rate: --frames frames at `rate` a second into `region` (window 1), their latencies.
Status PacedRun(Session& s, const std::string& region, double rate) {
  // Several clients' paced runs start together, after all of them have uploaded.
  std::this_thread::sleep_until(std::chrono::system_clock::time_point(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(
          std::chrono::duration<double>(s.options.start_at))));
  std::vector<double> latencies;
  StreamPlan plan = Plan(s, region, true, s.options.frames, 1);
  plan.rate = rate;
  plan.latencies_ms = &latencies;
  if (Status st = StreamIntoRegion(s.client->stub(), plan,
                                   [](uint32_t, const v1::SkinResponse&) { return Status::Ok(); });
      !st.ok()) {
    return st;
  }
  if (latencies.empty()) return Internal("the paced run answered no frame");
  std::sort(latencies.begin(), latencies.end());
  const auto at = [&](double q) {
    return latencies[std::min(latencies.size() - 1,
                              static_cast<std::size_t>(q * static_cast<double>(latencies.size())))];
  };
  const double period_ms = 1000.0 / rate;
  const auto late =
      std::count_if(latencies.begin(), latencies.end(), [&](double ms) { return ms > period_ms; });
  fmt::print(
      "paced: {} x {}: {} frames at {:.0f}/s{} into the GPU region (window 1): latency p50 "
      "{:.2f} ms, p99 {:.2f} ms, max {:.2f} ms; {} answered later than a period ({:.1f} ms)\n",
      s.options.vertices, s.options.influences, latencies.size(), rate,
      s.options.characters > 1 ? fmt::format(" in ticks of {}", s.options.characters) : "", at(0.5),
      at(0.99), latencies.back(), late, period_ms);
  return Status::Ok();
}

// The same frames into a shared-memory region of their own, skinned by `backend`.
Result<double> SpeedOverSharedMemory(Session& s, const std::string& backend) {
  auto region =
      client::SharedMemoryRegion::Create(client::SharedMemoryRegion::UniqueKey("gpu-region-cmp"),
                                         TickBytes(s) * s.options.window, s.options.shm_dir);
  if (!region.ok()) return region.status();
  const std::string name = "shm-compare-" + backend;
  if (auto info = s.client->RegisterRegion(name, **region); !info.ok()) return info.status();
  Result<double> speed = Speed(s, name, false, backend);
  // Unregistered before the region is unmapped here, whether the run passed or not.
  Status st =
      AfterCleanup(speed.ok() ? Status::Ok() : speed.status(), s.client->UnregisterRegion(name));
  if (!st.ok()) return st;
  return speed;
}

// --check and --draw into `region`, the one-frame region with the semaphore.
Status CheckAndDrawInto(Session& s, const VulkanDevice& device, const WaitedRegion& region) {
  const Options& options = s.options;
  fmt::print(
      "device '{}': GPU region '{}' of {} bytes registered {} ({} x {})\n", device.name(),
      region.name, region.buffer->allocation_bytes(),
      region.semaphore != nullptr ? "with a semaphore the server signals" : "without a semaphore",
      options.vertices, options.influences);
  if (options.check_frames > 0) {
    auto read_back = ReadBack::Create(device, TickBytes(s));
    if (!read_back.ok()) return read_back.status();
    uint32_t checked = 0;
    double worst = 0;
    if (Status st = Check(s, region, **read_back, &checked, &worst); !st.ok()) return st;
    fmt::print(
        "check: {} of {} frames ({}{}) equal the float64 reference ({}max position error {:.3g}), "
        "each read after {}\n",
        checked, options.check_frames, VertexEncodingName(options.encoding),
        options.characters > 1
            ? fmt::format(", ticks of {} characters, every character checked", options.characters)
            : "",
        options.encoding == VertexEncoding::kFloat32
            ? ""
            : "decoded, within float32's tolerance plus the encoding's bound; ",
        worst, region.semaphore != nullptr ? "a GPU wait on the semaphore" : "the answer");
    if (checked != options.check_frames) return Internal("not every frame was checked");
  }
  if (options.draw_path.empty()) return Status::Ok();
#if SKINSERVE_GPU_REGION_DRAW
  return Draw(s, device, region);
#else
  return FailedPrecondition(
      "--draw: this skinserve-gpu-region was built without its renderer (no glslangValidator "
      "or libpng when it was built)");
#endif
}

// --check and --draw, into the one-frame region with the semaphore, unregistered after.
Status CheckAndDraw(Session& s, const VulkanDevice& device) {
  if (s.options.check_frames == 0 && s.options.draw_path.empty()) return Status::Ok();
  Result<WaitedRegion> region = RegisterWaited(s, device);
  if (!region.ok()) return region.status();
  return UnregisterGpuAfter(s, region->name, CheckAndDrawInto(s, device, *region));
}

// " = C characters/s in ticks of N" after a rate of ticks (nothing for plain frames).
std::string InTicks(const Options& options, double frames_per_second) {
  if (options.characters == 1) return "";
  return fmt::format(" = {:.0f} characters/s in ticks of {}",
                     frames_per_second * options.characters, options.characters);
}

// The speed runs: into GPU region "vertices", then (--compare-shm) the same frames read back
// into shared memory by --backend and by --compare-backend on the server's CPUs.
Status SpeedRunsInto(Session& s) {
  const Options& options = s.options;
  if (options.rate > 0) return PacedRun(s, "vertices", options.rate);
  auto gpu = Speed(s, "vertices", true);
  if (!gpu.ok()) return gpu.status();
  fmt::print("gpu-region: {} x {}: {:.1f} frames/s{} ({} frames, window {}, {})\n",
             options.vertices, options.influences, *gpu, InTicks(options, *gpu), options.frames,
             options.window, VertexEncodingName(options.encoding));
  if (!options.compare_shm) return Status::Ok();
  auto shm = SpeedOverSharedMemory(s, options.backend);
  if (!shm.ok()) return shm.status();
  fmt::print("shm-readback: {} x {}: {:.1f} frames/s{}; gpu-region / shm = {:.2f}x\n",
             options.vertices, options.influences, *shm, InTicks(options, *shm), *gpu / *shm);
  if (options.compare_backend.empty()) return Status::Ok();
  auto cpu = SpeedOverSharedMemory(s, options.compare_backend);
  if (!cpu.ok()) return cpu.status();
  fmt::print(
      "{}-shm: {} x {}: {:.1f} frames/s{} (same frames and window, the server's CPUs, shared "
      "memory); gpu-region / {} = {:.2f}x\n",
      options.compare_backend, options.vertices, options.influences, *cpu, InTicks(options, *cpu),
      options.compare_backend, *gpu / *cpu);
  return Status::Ok();
}

// The speed runs into a GPU region of their own, unregistered after (before its buffer goes).
Status SpeedRuns(Session& s, const VulkanDevice& device) {
  const Options& options = s.options;
  auto buffer = ExportedBuffer::Create(device, TickBytes(s) * options.window);
  if (!buffer.ok()) return buffer.status();
  if (Status st = RegisterGpu(s, device, **buffer, "vertices"); !st.ok()) return st;
  fmt::print("device '{}': GPU region of {} bytes registered ({} x {}, window {})\n", device.name(),
             (*buffer)->allocation_bytes(), options.vertices, options.influences, options.window);
  return UnregisterGpuAfter(s, "vertices", SpeedRunsInto(s));
}

int Run(const Options& options) {
  Session s{.options = options};
  const auto fail = [](const Status& status) {
    fmt::print("FAIL: {}\n", status.ToString());
    return 1;
  };
  auto device = VulkanDevice::Create(options.vulkan_device, /*memory_fd=*/true, options.semaphore);
  if (!device.ok()) return fail(device.status());
  if (Status st = Prepare(s); !st.ok()) return fail(st);
  if (Status st = CheckAndDraw(s, **device); !st.ok()) return fail(st);
  if (options.frames > 0) {
    if (Status st = SpeedRuns(s, **device); !st.ok()) return fail(st);
  }
  fmt::print("PASS\n");
  return 0;
}

// --rate and --start-at: the paced run.
void AddPacedOptions(CLI::App& app, Options& o) {
  app.add_option("--rate", o.rate,
                 "instead of the speed runs, --frames frames at this many a second into the GPU "
                 "region (window 1), with their latencies (0: the speed runs)")
      ->check(CLI::Range(0.0, 100000.0))
      ->capture_default_str();
  app.add_option("--start-at", o.start_at,
                 "with --rate: start the paced run at this time (Unix seconds), so that several "
                 "clients run theirs together (0: at once)")
      ->capture_default_str();
}

}  // namespace
}  // namespace skinserve::gpu_region

int main(int argc, char** argv) {
  skinserve::gpu_region::Options o;
  CLI::App app{"skinserve-gpu-region: a headless Vulkan client of the server's GPU regions"};
  app.add_option("--target", o.target, "the server's Unix socket, unix:PATH")->required();
  app.add_option("--fd-socket", o.fd_socket, "the server's --gpu-fd-socket")->required();
  CLI::Option* mesh =
      app.add_option("--mesh", o.mesh_path,
                     "a glTF 2.0 character (.glb, or .gltf with its buffers) instead of the "
                     "synthetic one: all of its primitives as one mesh, its first clip's palettes "
                     "(frame f at f/30 s, looping), drawn as triangles; normals when it has them")
          ->check(CLI::ExistingFile);
  // The synthetic character's shape: a --mesh brings its own.
  app.add_option("--vertices", o.vertices, "vertices of the synthetic character")
      ->capture_default_str()
      ->excludes(mesh);
  app.add_option("--influences", o.influences, "bones per vertex of the synthetic character")
      ->capture_default_str()
      ->excludes(mesh);
  app.add_option("--frames", o.frames, "frames of the speed runs (0: none)")->capture_default_str();
  app.add_option("--characters-per-tick", o.characters,
                 "each frame a tick of this many characters (the synthetic character on a mesh "
                 "of its own each; a --mesh character repeated), into one region")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  skinserve::gpu_region::AddPacedOptions(app, o);
  app.add_option("--window", o.window, "frames in flight in the speed runs (one slot each)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--check", o.check_frames,
                 "test mode: this many frames, each copied back and compared with the float64 "
                 "reference")
      ->capture_default_str();
  app.add_flag("--normals", o.normals, "skin the synthetic character's normals too")
      ->excludes(mesh);
  app.add_option("--backend", o.backend)->capture_default_str();
  app.add_option("--shm-dir", o.shm_dir, "where the comparison's shared-memory region goes")
      ->capture_default_str();
  app.add_option("--compare-shm", o.compare_shm,
                 "after the GPU speed run, the same frames into a shared-memory region")
      ->capture_default_str();
  app.add_option("--compare-backend", o.compare_backend,
                 "with --compare-shm, the same frames into shared memory on this backend too "
                 "(\"\": none)")
      ->capture_default_str();
  app.add_option("--vulkan-device", o.vulkan_device, "device index (-1: first discrete GPU)")
      ->capture_default_str();
  app.add_option("--semaphore", o.semaphore,
                 "--check and --draw: register an exported semaphore the server signals per "
                 "frame, and wait on it on the GPU")
      ->capture_default_str();
  app.add_option("--draw", o.draw_path,
                 "draw the character mid-walk (the middle pose) from the GPU region into this PNG, "
                 "checked against the reference");
  std::string encoding = "float32";
  CLI::Option* encoded =
      app.add_option("--encoding", encoding,
                     "float32, float16 or snorm16: what the server writes into the regions "
                     "(--check decodes it)")
          ->check(CLI::IsMember({"float32", "float16", "snorm16"}))
          ->capture_default_str();
  app.add_option("--draw-size", o.draw_size, "the picture's width and height in pixels")
      ->check(CLI::Range(16, 4096))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  o.encoding = *skinserve::ParseVertexEncoding(encoding);  // one of IsMember's
  if (!o.draw_path.empty() && o.characters > 1) {
    fmt::print(stderr, "error: --draw draws one character: leave --characters-per-tick at 1\n");
    return 2;
  }
  if (!o.draw_path.empty() && o.encoding != skinserve::VertexEncoding::kFloat32) {
    fmt::print(stderr, "error: --draw draws float32 vertices: leave {} at float32\n",
               encoded->get_name());
    return 2;
  }
  return skinserve::gpu_region::Run(o);
}
