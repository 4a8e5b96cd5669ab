// skinserve-gpu-region: a headless Vulkan renderer's side of GPU regions
// (docs/serving/gpu-regions.md). It allocates a vertex buffer on the GPU, exports it as an
// opaque fd, hands the fd to the server (--fd-socket) and registers it (GpuRegions), then
// streams a synthetic character's palettes with every frame written into the buffer by
// the server's `opencl` backend. --check and --draw use a buffer of one frame registered
// with an exported semaphore (unless --semaphore false), which the server signals once per
// answered frame: each frame's GPU work waits on it (window 1, so the wait has run before
// the next frame is sent). --check copies each frame back and compares it with the float64
// reference; --draw draws the character mid-walk from the buffer (vertex_renderer.h) into
// a PNG and checks the picture against the reference's projected positions. The speed run
// streams --frames frames with --window in flight into a buffer without a semaphore, then
// the same frames into a shared-memory region (read back from the GPU into host memory)
// for comparison. Prints one summary line per run and PASS or FAIL.
#include <fmt/format.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>

#include "frame_streams.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/gpu_fd_handoff.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/region_layout.h"
#include "vulkan_device.h"
#if SKINSERVE_GPU_REGION_DRAW
#include "draw_check.h"
#include "png_file.h"
#include "vertex_renderer.h"
#endif

namespace skinserve::gpu_region {
namespace {

struct Options {
  std::string target, fd_socket, backend = "opencl", shm_dir = "/dev/shm";
  uint32_t vertices = 25000, influences = 2, frames = 600, window = 2, check_frames = 0;
  bool normals = false, compare_shm = true, semaphore = true;
  int vulkan_device = -1;
  std::string draw_path;  // --draw: the picture's PNG ("" none)
  uint32_t draw_size = 768;
};

struct Session {
  Options options;
  std::shared_ptr<const Mesh> mesh;
  std::string mesh_id;
  std::vector<std::string> palettes;  // a walk cycle's distinct poses, reused
  uint64_t slot_bytes = 0;
  std::unique_ptr<client::SkinClient> client;
  std::unique_ptr<v1::GpuRegions::Stub> gpu;
};

constexpr uint32_t kPoses = 64;

Status Prepare(Session& s) {
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = s.options.vertices,
                                               .influences = s.options.influences,
                                               .normals = s.options.normals,
                                               .seed = 7});
  auto mesh = Mesh::Create(arrays);
  if (!mesh.ok()) return mesh.status();
  s.mesh = *mesh;
  auto channel = client::MakeChannel(s.options.target);
  s.client = std::make_unique<client::SkinClient>(channel);
  s.gpu = v1::GpuRegions::NewStub(channel);
  auto info = s.client->Upload(arrays);
  if (!info.ok()) return info.status();
  s.mesh_id = info->mesh_id();
  for (uint32_t f = 0; f < kPoses; ++f) {
    const auto palette = MakeSyntheticPalette(s.mesh->joint_count(), 3, f);
    s.palettes.emplace_back(reinterpret_cast<const char*>(palette.data()),
                            palette.size() * sizeof(float));
  }
  const wire::RegionLayout layout =
      wire::LayoutInRegion(0, s.options.vertices, 1, VertexEncoding::kFloat32, s.options.normals);
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

StreamPlan Plan(const Session& s, const std::string& region, bool gpu, uint32_t frames,
                uint32_t window) {
  return {.mesh_id = s.mesh_id,
          .backend = s.options.backend,
          .region = region,
          .gpu = gpu,
          .frames = frames,
          .window = window,
          .slot_bytes = s.slot_bytes,
          .normals = s.options.normals,
          .palette = [&s](uint32_t f) -> const std::string& { return s.palettes[f % kPoses]; }};
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

Result<WaitedRegion> RegisterWaited(Session& s, const VulkanDevice& device) {
  WaitedRegion r;
  auto buffer = ExportedBuffer::Create(device, s.slot_bytes);
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

// Window 1: each frame copied back from the GPU (after waiting on the semaphore there) and
// compared with the reference.
Status Check(Session& s, const WaitedRegion& region, ReadBack& read_back, uint32_t* checked,
             double* worst) {
  const uint32_t v = s.options.vertices;
  return StreamIntoRegion(
      s.client->stub(), Plan(s, region.name, true, s.options.check_frames, 1),
      [&](uint32_t frame, const v1::SkinResponse& response) -> Status {
        const v1::RegionWrite& w = response.region_write();
        Result<const void*> bytes =
            read_back.Copy(*region.buffer, 0, w.end_offset(), region.wait());
        if (!bytes.ok()) return bytes.status();
        const auto* base = static_cast<const std::byte*>(*bytes);
        std::span<const float> positions(
            reinterpret_cast<const float*>(base + w.positions_offset()), 3ull * v);
        std::span<const float> normals;
        if (s.options.normals) {
          normals = {reinterpret_cast<const float*>(base + w.normals_offset()), 3ull * v};
        }
        const std::string& p = s.palettes[frame % kPoses];
        std::span<const float> palette(reinterpret_cast<const float*>(p.data()),
                                       p.size() / sizeof(float));
        const Deviation d = CompareWithReference(*s.mesh, palette, positions, normals);
        *worst = std::max(*worst, d.max_position_error);
        if (!d.within_tolerance()) {
          return Internal(fmt::format(
              "frame {}: position error {} (tolerance {}), normal error {} at vertex {}", frame,
              d.max_position_error, d.position_tolerance, d.max_normal_error, d.worst_vertex));
        }
        ++*checked;
        return Status::Ok();
      });
}

#if SKINSERVE_GPU_REGION_DRAW
// The float64 reference of pose `f` and the front view that frames it.
struct DrawnPose {
  ReferenceFrame reference;
  Transform transform;
};

DrawnPose ReferencePose(const Session& s, uint32_t f, uint32_t size) {
  const std::string& p = s.palettes[f % kPoses];
  DrawnPose pose{.reference = ReferenceSkin(
                     *s.mesh, std::span<const float>(reinterpret_cast<const float*>(p.data()),
                                                     p.size() / sizeof(float)))};
  std::array<float, 3> lo = {1e30f, 1e30f, 1e30f}, hi = {-1e30f, -1e30f, -1e30f};
  for (std::size_t i = 0; i < pose.reference.positions.size(); ++i) {
    const float x = static_cast<float>(pose.reference.positions[i]);
    lo[i % 3] = std::min(lo[i % 3], x);
    hi[i % 3] = std::max(hi[i % 3], x);
  }
  pose.transform = FrontView(lo, hi, size, size);
  return pose;
}

// --draw: frames 0 to the walk's middle pose, each drawn from the GPU region by a
// submission that waits on the semaphore; the last one's picture checked against the
// reference and written as a PNG.
Status Draw(Session& s, const VulkanDevice& device, const WaitedRegion& region) {
  const uint32_t size = s.options.draw_size, last = kPoses / 2;
  auto renderer = VertexRenderer::Create(device, size, size);
  if (!renderer.ok()) return renderer.status();
  const DrawnPose pose = ReferencePose(s, last, size);
  std::span<const uint8_t> pixels;
  Status streamed =
      StreamIntoRegion(s.client->stub(), Plan(s, region.name, true, last + 1, 1),
                       [&](uint32_t frame, const v1::SkinResponse& response) -> Status {
                         const v1::RegionWrite& w = response.region_write();
                         auto drawn = (*renderer)->Draw({.vertices = region.buffer->buffer(),
                                                         .positions_offset = w.positions_offset(),
                                                         .normals_offset = w.normals_offset(),
                                                         .normals = s.options.normals,
                                                         .vertex_count = s.options.vertices,
                                                         .external = true,
                                                         .wait = region.wait(),
                                                         .transform = pose.transform});
                         if (!drawn.ok()) return drawn.status();
                         if (frame == last) pixels = *drawn;
                         return Status::Ok();
                       });
  if (!streamed.ok()) return streamed;
  const PictureCheck check =
      CheckPicture(pixels, size, size, pose.reference.positions, pose.transform);
  if (Status st = WritePng(s.options.draw_path, pixels, size, size); !st.ok()) return st;
  fmt::print(
      "draw: frame {} (the walk's middle pose) drawn from the GPU region into {} ({} x {}): "
      "{}\n",
      last, s.options.draw_path, size, size, check.ToString());
  if (!check.ok()) return Internal("the picture does not show the reference's positions");
  return Status::Ok();
}
#endif

// frames/s of `frames` frames into `region` with the window in flight.
Result<double> Speed(Session& s, const std::string& region, bool gpu) {
  const auto started = std::chrono::steady_clock::now();
  Status status =
      StreamIntoRegion(s.client->stub(), Plan(s, region, gpu, s.options.frames, s.options.window),
                       [](uint32_t, const v1::SkinResponse&) { return Status::Ok(); });
  if (!status.ok()) return status;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return s.options.frames / seconds;
}

Result<double> SpeedOverSharedMemory(Session& s) {
  auto region =
      client::SharedMemoryRegion::Create(client::SharedMemoryRegion::UniqueKey("gpu-region-cmp"),
                                         s.slot_bytes * s.options.window, s.options.shm_dir);
  if (!region.ok()) return region.status();
  if (auto info = s.client->RegisterRegion("shm-compare", **region); !info.ok()) {
    return info.status();
  }
  return Speed(s, "shm-compare", false);
}

// --check and --draw, into the one-frame region with the semaphore.
Status CheckAndDraw(Session& s, const VulkanDevice& device) {
  const Options& options = s.options;
  if (options.check_frames == 0 && options.draw_path.empty()) return Status::Ok();
  Result<WaitedRegion> region = RegisterWaited(s, device);
  if (!region.ok()) return region.status();
  fmt::print(
      "device '{}': GPU region '{}' of {} bytes registered {} ({} x {})\n", device.name(),
      region->name, region->buffer->allocation_bytes(),
      region->semaphore != nullptr ? "with a semaphore the server signals" : "without a semaphore",
      options.vertices, options.influences);
  if (options.check_frames > 0) {
    auto read_back = ReadBack::Create(device, s.slot_bytes);
    if (!read_back.ok()) return read_back.status();
    uint32_t checked = 0;
    double worst = 0;
    if (Status st = Check(s, *region, **read_back, &checked, &worst); !st.ok()) return st;
    fmt::print(
        "check: {} of {} frames equal the float64 reference (max position error {:.3g}), each "
        "read after {}\n",
        checked, options.check_frames, worst,
        region->semaphore != nullptr ? "a GPU wait on the semaphore" : "the answer");
    if (checked != options.check_frames) return Internal("not every frame was checked");
  }
  if (options.draw_path.empty()) return Status::Ok();
#if SKINSERVE_GPU_REGION_DRAW
  return Draw(s, device, *region);
#else
  return FailedPrecondition(
      "--draw: this skinserve-gpu-region was built without its renderer (no glslangValidator "
      "or libpng when it was built)");
#endif
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
    auto buffer = ExportedBuffer::Create(**device, s.slot_bytes * options.window);
    if (!buffer.ok()) return fail(buffer.status());
    if (Status st = RegisterGpu(s, **device, **buffer, "vertices"); !st.ok()) return fail(st);
    fmt::print("device '{}': GPU region of {} bytes registered ({} x {}, window {})\n",
               (*device)->name(), (*buffer)->allocation_bytes(), options.vertices,
               options.influences, options.window);
    auto gpu = Speed(s, "vertices", true);
    if (!gpu.ok()) return fail(gpu.status());
    fmt::print("gpu-region: {} x {}: {:.1f} frames/s ({} frames, window {})\n", options.vertices,
               options.influences, *gpu, options.frames, options.window);
    if (options.compare_shm) {
      auto shm = SpeedOverSharedMemory(s);
      if (!shm.ok()) return fail(shm.status());
      fmt::print("shm-readback: {} x {}: {:.1f} frames/s; gpu-region / shm = {:.2f}x\n",
                 options.vertices, options.influences, *shm, *gpu / *shm);
    }
  }
  fmt::print("PASS\n");
  return 0;
}

}  // namespace
}  // namespace skinserve::gpu_region

int main(int argc, char** argv) {
  skinserve::gpu_region::Options o;
  CLI::App app{"skinserve-gpu-region: a headless Vulkan client of the server's GPU regions"};
  app.add_option("--target", o.target, "the server's Unix socket, unix:PATH")->required();
  app.add_option("--fd-socket", o.fd_socket, "the server's --gpu-fd-socket")->required();
  app.add_option("--vertices", o.vertices, "vertices of the synthetic character")
      ->capture_default_str();
  app.add_option("--influences", o.influences, "bones per vertex")->capture_default_str();
  app.add_option("--frames", o.frames, "frames of the speed runs (0: none)")->capture_default_str();
  app.add_option("--window", o.window, "frames in flight in the speed runs (one slot each)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--check", o.check_frames,
                 "test mode: this many frames, each copied back and compared with the float64 "
                 "reference")
      ->capture_default_str();
  app.add_flag("--normals", o.normals, "skin normals too");
  app.add_option("--backend", o.backend)->capture_default_str();
  app.add_option("--shm-dir", o.shm_dir, "where the comparison's shared-memory region goes")
      ->capture_default_str();
  app.add_option("--compare-shm", o.compare_shm,
                 "after the GPU speed run, the same frames into a shared-memory region")
      ->capture_default_str();
  app.add_option("--vulkan-device", o.vulkan_device, "device index (-1: first discrete GPU)")
      ->capture_default_str();
  app.add_option("--semaphore", o.semaphore,
                 "--check and --draw: register an exported semaphore the server signals per "
                 "frame, and wait on it on the GPU")
      ->capture_default_str();
  app.add_option("--draw", o.draw_path,
                 "draw the character mid-walk from the GPU region into this PNG, checked against "
                 "the reference");
  app.add_option("--draw-size", o.draw_size, "the picture's width and height in pixels")
      ->check(CLI::Range(16, 4096))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  return skinserve::gpu_region::Run(o);
}
