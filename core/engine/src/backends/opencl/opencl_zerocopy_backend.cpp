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
#include "backends/opencl/opencl_backend_base.h"
#include "backends/opencl/opencl_backends.h"

namespace skinserve {
namespace {

// `what` over `bytes` of host memory at `host`, in place (CL_MEM_USE_HOST_PTR) with `access`.
Status WrapHostMemory(OpenClRuntime& runtime, const char* what, cl_mem_flags access,
                      std::size_t bytes, const void* host, ClBuffer* buffer) {
  auto created = runtime.CreateBuffer(what, access | CL_MEM_USE_HOST_PTR, bytes, host);
  if (!created.ok()) return created.status();
  *buffer = std::move(created).value();
  return Status::Ok();
}

class OpenClZeroCopyBackend final : public OpenClBackendBase {
 public:
  OpenClZeroCopyBackend(const std::shared_ptr<OpenClRuntime>& runtime,
                        std::shared_ptr<OpenClEncoder> encoder)
      : OpenClBackendBase(runtime, std::move(encoder), CL_MEM_USE_HOST_PTR,
                          OpenClBackendInfo(*runtime, "opencl-zerocopy",
                                            "OpenCL kernel on host memory in place, no copies",
                                            runtime->is_cpu() ? runtime->compute_units() : 1)) {}

 private:
  Status SkinPalette(const OpenClPreparedMesh& prepared, const SkinFrame& frame) override {
    const bool with_normals = frame.wants_normals();
    const bool with_tangents = frame.wants_tangents();
    if (frame.encoded.active()) return SkinEncoded(prepared, frame);
    // Wrapping host memory is cheap (well under a microsecond on PoCL): per call, so
    // concurrent calls never share an output buffer.
    ClBuffer palette, out_positions, out_normals, out_tangents, morph_weights;
    if (Status s = WrapInputs(prepared, frame, &palette, &morph_weights); !s.ok()) return s;
    if (Status s =
            WrapHostMemory(runtime(), "output positions", CL_MEM_WRITE_ONLY,
                           frame.positions.size_bytes(), frame.positions.data(), &out_positions);
        !s.ok()) {
      return s;
    }
    if (with_normals) {
      if (Status s = WrapHostMemory(runtime(), "output normals", CL_MEM_WRITE_ONLY,
                                    frame.normals.size_bytes(), frame.normals.data(), &out_normals);
          !s.ok()) {
        return s;
      }
    }
    if (with_tangents) {
      if (Status s =
              WrapHostMemory(runtime(), "output tangents", CL_MEM_WRITE_ONLY,
                             frame.tangents.size_bytes(), frame.tangents.data(), &out_tangents);
          !s.ok()) {
        return s;
      }
    }
    SkinKernelArgs args = KernelArgs(prepared, frame.method, palette.get(), out_positions.get(),
                                     out_normals.get(), out_tangents.get());
    auto lane = runtime().AcquireLane();
    ClEvents kernels, transfers;
    Status status =
        EnqueueMorphAndSkin(*lane, prepared, frame, morph_weights.get(), &args, kernels);
    if (status.ok()) {
      status = SyncToHost(*lane, out_positions.get(), frame.positions.size_bytes(), transfers);
    }
    if (status.ok() && with_normals) {
      status = SyncToHost(*lane, out_normals.get(), frame.normals.size_bytes(), transfers);
    }
    if (status.ok() && with_tangents) {
      status = SyncToHost(*lane, out_tangents.get(), frame.tangents.size_bytes(), transfers);
    }
    return Finish(*lane, status, frame, kernels, transfers);
  }

  // The frame's palette and (a frame with an active target) its morph weights, in place.
  Status WrapInputs(const OpenClPreparedMesh& prepared, const SkinFrame& frame, ClBuffer* palette,
                    ClBuffer* morph_weights) {
    if (Status s = WrapHostMemory(runtime(), "palette", CL_MEM_READ_ONLY,
                                  frame.palette.size_bytes(), frame.palette.data(), palette);
        !s.ok()) {
      return s;
    }
    if (!MorphsOnDevice(frame, prepared.morph)) return Status::Ok();
    return WrapHostMemory(runtime(), "morph weights", CL_MEM_READ_ONLY,
                          frame.morph_weights.size_bytes(), frame.morph_weights.data(),
                          morph_weights);
  }

  // In order on the compute queue: the morph (a frame with an active target), then the skin.
  Status EnqueueMorphAndSkin(OpenClLane& lane, const OpenClPreparedMesh& prepared,
                             const SkinFrame& frame, cl_mem morph_weights, SkinKernelArgs* args,
                             ClEvents& kernels) {
    const Mesh& mesh = prepared.mesh();
    if (Status s = EnqueueFrameMorph(runtime(), lane, mesh, prepared.morph, morph_weights, frame,
                                     args, kernels);
        !s.ok()) {
      return s;
    }
    return runtime().EnqueueSkin(lane, mesh, *args, 0, mesh.vertex_count(), kernels.Next());
  }

  // Encoded output: the floats go to the lane's device buffers, and the encoder's kernels
  // write the caller's encoded arrays in place (opencl_encode.h).
  Status SkinEncoded(const OpenClPreparedMesh& prepared, const SkinFrame& frame) {
    ClBuffer palette, morph_weights;
    if (Status s = WrapInputs(prepared, frame, &palette, &morph_weights); !s.ok()) return s;
    const Mesh& mesh = prepared.mesh();
    auto lane = runtime().AcquireLane();
    if (Status s = GrowLaneOutputs(*lane, frame, mesh.vertex_count()); !s.ok()) return s;
    SkinKernelArgs args =
        KernelArgs(prepared, frame.method, palette.get(), lane->out_positions.get(),
                   frame.wants_normals() ? lane->out_normals.get() : nullptr,
                   frame.wants_tangents() ? lane->out_tangents.get() : nullptr);
    ClEvents kernels, transfers;
    Status status =
        EnqueueMorphAndSkin(*lane, prepared, frame, morph_weights.get(), &args, kernels);
    if (status.ok()) {
      status = encoder().Encode(*lane, args, mesh.vertex_count(), frame, /*zero_copy=*/true,
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
    return RecordDeviceTiming(kernels, transfers, runtime().device_timing(), frame.device_timing);
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
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                                   std::shared_ptr<OpenClEncoder> encoder) {
  return std::make_unique<OpenClZeroCopyBackend>(std::move(runtime), std::move(encoder));
}

}  // namespace skinserve
