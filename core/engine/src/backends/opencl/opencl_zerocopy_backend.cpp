// `opencl-zerocopy`: stands for the paper's OpenCL-OpenGL interop, where the data never
// leaves the buffers the renderer uses. Every buffer wraps host memory in place
// (CL_MEM_USE_HOST_PTR): the mesh's own aligned arrays (tangents included), the frame's
// palette and the caller's output spans (positions, normals, tangents). PoCL's CPU device runs the
// kernel on that memory (its device pointer is the host pointer), so there is no write before and
// no read after; mapping the outputs is only the synchronisation the OpenCL memory model asks for,
// and a no-op on PoCL. That holds for any float-aligned pointer, not only 64-byte aligned ones:
// checked with POCL_DEBUG=memory on PoCL 3.1 ("Basic device ALLOC" at the host address,
// kernel writes visible before the map).
//
// On a device with memory of its own (a discrete GPU) the same buffers mean: the data
// lives in host memory and no transfer is enqueued; whatever crosses PCIe is the driver's
// doing. NVIDIA's driver copies a USE_HOST_PTR buffer to the device when a kernel first
// uses it (the mesh: once, then cached, as the buffers are read-only) and copies the
// outputs back at the map, from the device into the caller's pageable memory. The map is
// profiled as this frame's transfer time. docs/backends/opencl.md ("Figure 5") says when that wins.
//
// Morph targets: the mesh's targets are wrapped in place too, and so are a frame's active
// weights; a frame with an active target runs the morph kernel into the lane's morphed
// buffers (device memory, grown like the copy backend's per-lane buffers), which
// the skinning kernel then reads (opencl_morph.h).
#include "backends/common/dual_quaternion_palette.h"
#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_encode.h"
#include "backends/opencl/opencl_morph.h"
#include "backends/opencl/opencl_quantized.h"

namespace skinserve {
namespace {

struct ZeroCopyPreparedMesh final : PreparedMesh {
  using PreparedMesh::PreparedMesh;
  ClBuffer positions, normals, tangents, joints, weights;
  OpenClMorphTargets morph;
};

class OpenClZeroCopyBackend final : public Backend {
 public:
  OpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                        std::shared_ptr<OpenClEncoder> encoder)
      : runtime_(std::move(runtime)),
        encoder_(std::move(encoder)),
        info_(OpenClBackendInfo(*runtime_, "opencl-zerocopy",
                                "OpenCL kernel on host memory in place, no copies",
                                runtime_->is_cpu() ? runtime_->compute_units() : 1)) {}
  const BackendInfo& info() const override { return info_; }

  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    // The prepared mesh holds the Mesh alive, and with it the memory these buffers wrap.
    auto prepared = std::make_unique<ZeroCopyPreparedMesh>(mesh);
    if (mesh->quantized_rest() != nullptr) {  // the integers only (opencl_quantized.h)
      if (Status s = PrepareQuantizedMesh(
              *runtime_, *mesh, CL_MEM_USE_HOST_PTR, &prepared->positions, &prepared->normals,
              &prepared->tangents, &prepared->joints, &prepared->weights);
          !s.ok()) {
        return s;
      }
      return std::unique_ptr<PreparedMesh>(std::move(prepared));
    }
    auto wrap = [&](const char* what, ClBuffer* buffer, auto span) -> Status {
      auto created = runtime_->CreateBuffer(what, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                            span.size_bytes(), span.data());
      if (!created.ok()) return created.status();
      *buffer = std::move(created).value();
      return Status::Ok();
    };
    if (Status s = wrap("positions", &prepared->positions, mesh->positions()); !s.ok()) return s;
    if (Status s = wrap("joints", &prepared->joints, mesh->joints()); !s.ok()) return s;
    if (Status s = wrap("weights", &prepared->weights, mesh->weights()); !s.ok()) return s;
    if (mesh->has_normals()) {
      if (Status s = wrap("normals", &prepared->normals, mesh->normals()); !s.ok()) return s;
    }
    if (mesh->has_tangents()) {
      if (Status s = wrap("tangents", &prepared->tangents, mesh->tangents()); !s.ok()) return s;
    }
    auto morph = CreateMorphTargets(*runtime_, *mesh, CL_MEM_USE_HOST_PTR);
    if (!morph.ok()) return morph.status();
    prepared->morph = std::move(morph).value();
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }

  Status Skin(const PreparedMesh& base, const SkinFrame& frame) override {
    return SkinWithKernelPalette(info_.id, base, frame, [&](const SkinFrame& in_kernel_layout) {
      return SkinPalette(base, in_kernel_layout);
    });
  }

 private:
  // Skin() with frame.palette in the layout of frame.method's kernels.
  Status SkinPalette(const PreparedMesh& base, const SkinFrame& frame) {
    const auto& prepared = static_cast<const ZeroCopyPreparedMesh&>(base);
    if (Status s = CheckOpenClOutputs(prepared.mesh(), frame); !s.ok()) return s;
    const bool with_normals = frame.wants_normals();
    const bool with_tangents = frame.wants_tangents();
    if (frame.encoded.active()) return SkinEncoded(prepared, frame, with_normals, with_tangents);
    // Wrapping host memory is cheap (well under a microsecond on PoCL): per call, so
    // concurrent calls never share an output buffer.
    auto palette = runtime_->CreateBuffer("palette", CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                          frame.palette.size_bytes(), frame.palette.data());
    if (!palette.ok()) return palette.status();
    auto out_positions =
        runtime_->CreateBuffer("output positions", CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                               frame.positions.size_bytes(), frame.positions.data());
    if (!out_positions.ok()) return out_positions.status();
    ClBuffer out_normals;
    if (with_normals) {
      auto created =
          runtime_->CreateBuffer("output normals", CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                 frame.normals.size_bytes(), frame.normals.data());
      if (!created.ok()) return created.status();
      out_normals = std::move(created).value();
    }
    ClBuffer out_tangents;
    if (with_tangents) {
      auto created =
          runtime_->CreateBuffer("output tangents", CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                 frame.tangents.size_bytes(), frame.tangents.data());
      if (!created.ok()) return created.status();
      out_tangents = std::move(created).value();
    }
    SkinKernelArgs args{.method = frame.method,
                        .palette = palette->get(),
                        .joints = prepared.joints.get(),
                        .weights = prepared.weights.get(),
                        .positions = prepared.positions.get(),
                        .out_positions = out_positions->get()};
    if (with_normals) {
      args.normals = prepared.normals.get();
      args.out_normals = out_normals.get();
    }
    if (with_tangents) {
      args.tangents = prepared.tangents.get();
      args.out_tangents = out_tangents.get();
    }
    ClBuffer morph_weights;
    if (MorphsOnDevice(frame, prepared.morph)) {
      auto wrapped =
          runtime_->CreateBuffer("morph weights", CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                 frame.morph_weights.size_bytes(), frame.morph_weights.data());
      if (!wrapped.ok()) return wrapped.status();
      morph_weights = std::move(wrapped).value();
    }
    auto lane = runtime_->AcquireLane();
    ClEvents kernels, transfers;
    // In order on the compute queue: the morph (a frame with an active target), then the skin.
    Status status = EnqueueFrameMorph(*runtime_, *lane, prepared.mesh(), prepared.morph,
                                      morph_weights.get(), frame, &args, kernels);
    if (status.ok()) {
      status = runtime_->EnqueueSkin(*lane, prepared.mesh(), args, 0,
                                     prepared.mesh().vertex_count(), kernels.Next());
    }
    if (status.ok()) {
      status = SyncToHost(*lane, out_positions->get(), frame.positions.size_bytes(), transfers);
    }
    if (status.ok() && with_normals) {
      status = SyncToHost(*lane, out_normals.get(), frame.normals.size_bytes(), transfers);
    }
    if (status.ok() && with_tangents) {
      status = SyncToHost(*lane, out_tangents.get(), frame.tangents.size_bytes(), transfers);
    }
    return Finish(*lane, status, frame, kernels, transfers);
  }

  // Encoded output: the floats go to the lane's device buffers, and the encoder's kernels
  // write the caller's encoded arrays in place (opencl_encode.h).
  Status SkinEncoded(const ZeroCopyPreparedMesh& prepared, const SkinFrame& frame,
                     bool with_normals, bool with_tangents) {
    auto palette = runtime_->CreateBuffer("palette", CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                          frame.palette.size_bytes(), frame.palette.data());
    if (!palette.ok()) return palette.status();
    ClBuffer morph_weights;
    if (MorphsOnDevice(frame, prepared.morph)) {
      auto wrapped =
          runtime_->CreateBuffer("morph weights", CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                 frame.morph_weights.size_bytes(), frame.morph_weights.data());
      if (!wrapped.ok()) return wrapped.status();
      morph_weights = std::move(wrapped).value();
    }
    const Mesh& mesh = prepared.mesh();
    const std::size_t floats = 3ull * mesh.vertex_count() * sizeof(float);
    auto lane = runtime_->AcquireLane();
    Status status = runtime_->GrowBuffer("output positions", CL_MEM_READ_WRITE, floats,
                                         &lane->out_positions, &lane->positions_bytes);
    if (status.ok() && with_normals) {
      status = runtime_->GrowBuffer("output normals", CL_MEM_READ_WRITE, floats, &lane->out_normals,
                                    &lane->normals_bytes);
    }
    if (status.ok() && with_tangents) {
      status = runtime_->GrowBuffer("output tangents", CL_MEM_READ_WRITE, floats / 3 * 4,
                                    &lane->out_tangents, &lane->tangents_bytes);
    }
    if (!status.ok()) return status;
    SkinKernelArgs args{.method = frame.method,
                        .palette = palette->get(),
                        .joints = prepared.joints.get(),
                        .weights = prepared.weights.get(),
                        .positions = prepared.positions.get(),
                        .out_positions = lane->out_positions.get()};
    if (with_normals) {
      args.normals = prepared.normals.get();
      args.out_normals = lane->out_normals.get();
    }
    if (with_tangents) {
      args.tangents = prepared.tangents.get();
      args.out_tangents = lane->out_tangents.get();
    }
    ClEvents kernels, transfers;
    status = EnqueueFrameMorph(*runtime_, *lane, mesh, prepared.morph, morph_weights.get(), frame,
                               &args, kernels);
    if (status.ok()) {
      status = runtime_->EnqueueSkin(*lane, mesh, args, 0, mesh.vertex_count(), kernels.Next());
    }
    if (status.ok()) {
      status = encoder_->Encode(*lane, args, mesh.vertex_count(), frame, /*zero_copy=*/true,
                                kernels, transfers);
    }
    return Finish(*lane, status, frame, kernels, transfers);
  }

  // One wait for the whole in-order sequence (kernels, maps, unmaps), also after an error:
  // the buffers wrap the caller's memory and must be idle when Skin() returns. Then the
  // frame's device timing.
  Status Finish(OpenClLane& lane, Status status, const SkinFrame& frame, const ClEvents& kernels,
                const ClEvents& transfers) {
    if (cl_int err = clFinish(lane.compute); err != CL_SUCCESS && status.ok()) {
      status = ClError("clFinish", err);
    }
    if (!status.ok()) return status;
    return RecordDeviceTiming(kernels, transfers, frame.device_timing);
  }

  // Enqueues a map and an unmap: they make the kernel's writes visible in the host memory
  // the buffer wraps. Non-blocking: the in-order queue orders them after the kernel, and
  // the caller's clFinish is the one wait (a blocking map would be a second one).
  Status SyncToHost(OpenClLane& lane, cl_mem buffer, std::size_t bytes, ClEvents& transfers) {
    cl_int err = CL_SUCCESS;
    void* mapped = clEnqueueMapBuffer(lane.compute, buffer, CL_FALSE, CL_MAP_READ, 0, bytes, 0,
                                      nullptr, transfers.Next(), &err);
    if (err != CL_SUCCESS) return ClError("clEnqueueMapBuffer(output)", err);
    err = clEnqueueUnmapMemObject(lane.compute, buffer, mapped, 0, nullptr, nullptr);
    if (err != CL_SUCCESS) return ClError("clEnqueueUnmapMemObject(output)", err);
    return Status::Ok();
  }

  std::shared_ptr<OpenClRuntime> runtime_;
  std::shared_ptr<OpenClEncoder> encoder_;
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                                   std::shared_ptr<OpenClEncoder> encoder) {
  return std::make_unique<OpenClZeroCopyBackend>(std::move(runtime), std::move(encoder));
}

}  // namespace skinserve
