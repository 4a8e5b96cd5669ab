// `opencl`: the paper's plain OpenCL path. The mesh is copied into device buffers once (its
// tangents and morph targets too); each frame writes the palette (and its active morph weights) to
// the device and reads the result back. A frame with an active target runs the morph kernel first,
// and the skinning kernels read its morphed rest arrays (opencl_morph.h).
//
// On a device with memory of its own (a discrete GPU) every frame crosses PCIe, so:
//  - the palette and the results travel through page-locked (pinned) host memory of the
//    frame's lane, which the DMA engine reads and writes at the link's speed (pageable
//    memory makes the driver stage each transfer through its own pinned buffers);
//  - the frame runs in chunks: chunk k's kernel on the lane's compute queue, its read-back
//    on the lane's transfer queue after that kernel's event, so the read-back of one chunk
//    overlaps the kernel of the next, and the host copies chunk k out of pinned memory
//    while chunk k + 1 is still crossing the link, with the engine's threads that no other
//    frame's copy-out is using (one frame alone: all of them; see Lease::copy_threads);
//  - frames of several compute threads run on different lanes at once, so one frame's
//    read-back also overlaps another's upload and kernels.
// On a device that shares host memory (PoCL) the frame is one write, one kernel and one
// read straight from and into the caller's memory: staging would only add a copy.
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <vector>

#include "backends/opencl/opencl_backend_base.h"
#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_device_memory.h"

namespace skinserve {
namespace {

// Copies `bytes` with up to `threads` threads (large copies only).
void ParallelCopy(void* to, const void* from, std::size_t bytes, int threads) {
  constexpr std::size_t kPerThreadMin = 1u << 20;
  const int use = static_cast<int>(
      std::clamp<std::size_t>(bytes / kPerThreadMin, 1, static_cast<std::size_t>(threads)));
  if (use == 1) {
    std::memcpy(to, from, bytes);
    return;
  }
  const std::size_t piece = (bytes / use + 63) / 64 * 64;
#pragma omp parallel for num_threads(use) schedule(static)
  for (int t = 0; t < use; ++t) {
    const std::size_t begin = std::min(bytes, piece * t), end = std::min(bytes, begin + piece);
    std::memcpy(static_cast<char*>(to) + begin, static_cast<const char*>(from) + begin,
                end - begin);
  }
}

class OpenClCopyBackend final : public OpenClBackendBase {
 public:
  OpenClCopyBackend(const std::shared_ptr<OpenClRuntime>& runtime,
                    std::shared_ptr<OpenClEncoder> encoder)
      : OpenClBackendBase(
            runtime, std::move(encoder), CL_MEM_COPY_HOST_PTR,
            OpenClBackendInfo(
                *runtime, "opencl",
                runtime->staging()
                    ? "OpenCL kernel; palette written and result read back per frame "
                      "through pinned memory, in overlapped chunks"
                    : "OpenCL kernel; palette written and result read back per frame",
                // Staged: a frame waits on the device and then copies with the threads other
                // frames leave free, so it holds one compute thread of the engine.
                runtime->staging() ? 1 : runtime->compute_units())) {}

  // GPU regions: only this backend imports device memory (opencl_device_memory.h).
  Result<std::shared_ptr<DeviceMemory>> ImportDeviceMemory(
      const DeviceMemoryImport& import) override {
    return ImportOpenClDeviceMemory(runtime(), info().id, import);
  }

  // A tick's characters into GPU regions: the float32 frames enqueued one after another on
  // one lane (each its palette from a slot of its own, its kernel into the lane's buffers,
  // which the in-order queue reuses safely, its copies into the memory), then one wait for
  // all of them. Encoded frames wait for their flag and box anyway: they run as Skin does,
  // first.
  void SkinDeviceFrames(std::span<const PreparedMesh* const> prepared,
                        std::span<const SkinFrame> frames, std::span<Status> statuses) override {
    // The others first, each on a lane of its own and waited for: before this batch holds
    // a lane (a device sharing host memory has one) or a memory's lock.
    const auto batched = [&](std::size_t i) {
      return frames[i].device.active() && frames[i].device.encoding == VertexEncoding::kFloat32;
    };
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (!batched(i)) statuses[i] = Skin(*prepared[i], frames[i]);
    }
    auto lane = runtime().AcquireLane();
    std::byte* slots = nullptr;
    const std::size_t slot_bytes = PaletteSlotBytes(frames);
    std::vector<std::byte> host_slots;  // a device sharing host memory: no pinned staging
    if (runtime().staging()) {
      Status s = runtime().GrowPinned(lane->compute, "pinned batch palettes",
                                      slot_bytes * frames.size(), &lane->pinned_batch_palettes);
      if (!s.ok()) {
        for (std::size_t i = 0; i < frames.size(); ++i) {
          if (batched(i)) statuses[i] = s;
        }
        return;
      }
      slots = static_cast<std::byte*>(lane->pinned_batch_palettes.host);
    } else {
      host_slots.resize(slot_bytes * frames.size());
      slots = host_slots.data();
    }
    DeviceOutputBatch out(*lane);
    std::deque<ClEvents> kernels(frames.size()), transfers(frames.size());
    std::vector<std::size_t> enqueued;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (!batched(i)) continue;
      statuses[i] = InKernelLayout(*prepared[i], frames[i], [&](const auto& mesh, const auto& f) {
        return EnqueueDeviceFrame(*lane, mesh, f, slots + i * slot_bytes, out, kernels[i],
                                  transfers[i]);
      });
      if (statuses[i].ok()) enqueued.push_back(i);
    }
    const Status finished = out.Finish();
    for (std::size_t i : enqueued) {
      statuses[i] = finished.ok()
                        ? RecordDeviceTiming(kernels[i], transfers[i], frames[i].device_timing)
                        : finished;
    }
  }

 private:
  Status SkinPalette(const OpenClPreparedMesh& prepared, const SkinFrame& frame) override {
    const bool with_normals = frame.wants_normals();
    const bool with_tangents = frame.wants_tangents();
    auto lane = runtime().AcquireLane();
    if (Status s = Reserve(*lane, frame, prepared.mesh().vertex_count()); !s.ok()) return s;
    ClEvents kernels, transfers;
    SkinKernelArgs args =
        KernelArgs(prepared, frame.method, lane->palette.get(), lane->out_positions.get(),
                   with_normals ? lane->out_normals.get() : nullptr,
                   with_tangents ? lane->out_tangents.get() : nullptr);
    Status status = Morph(*lane, prepared, frame, &args, kernels, transfers);
    if (status.ok() && frame.device.active()) {  // a GPU region (opencl_device_memory.h)
      status = EnqueueWholeFrame(*lane, prepared, frame, args, kernels, transfers);
      const uint32_t vertices = prepared.mesh().vertex_count();
      if (status.ok() && frame.device.encoding != VertexEncoding::kFloat32) {
        status = encoder().EncodeIntoDevice(*lane, args, vertices, frame, kernels, transfers);
      } else if (status.ok()) {
        status = WriteDevicePieces(*lane, frame, Float32DevicePieces(args, vertices, frame.device),
                                   transfers);
      }
    } else if (status.ok() && frame.encoded.active()) {
      status = SkinEncoded(*lane, prepared, frame, args, kernels, transfers);
    } else if (status.ok()) {
      status = runtime().staging() ? SkinStaged(*lane, lane.copy_threads(), prepared, frame, args,
                                                kernels, transfers)
                                   : SkinDirect(*lane, prepared, frame, args, kernels, transfers);
    }
    if (!status.ok()) {
      // Enqueued commands may still use the lane's buffers (and, direct, the caller's
      // memory): the lane is idle before it is handed on.
      clFinish(lane->compute);
      clFinish(lane->transfer);
      return status;
    }
    return RecordDeviceTiming(kernels, transfers, frame.device_timing);
  }

  // The largest palette of `frames` (in bytes, rounded to 64): a batch's slot.
  static std::size_t PaletteSlotBytes(std::span<const SkinFrame> frames) {
    std::size_t most = 0;
    for (const SkinFrame& f : frames) most = std::max(most, f.palette.size_bytes());
    return (most + 63) / 64 * 64;
  }

  // One frame of a device batch, enqueued on `lane` without a wait: its morph (if any), its
  // palette (copied into `slot`, which stays the frame's until the batch's wait), its
  // kernel, its copies into the device memory.
  Status EnqueueDeviceFrame(OpenClLane& lane, const OpenClPreparedMesh& prepared,
                            const SkinFrame& frame, std::byte* slot, DeviceOutputBatch& out,
                            ClEvents& kernels, ClEvents& transfers) {
    const uint32_t vertices = prepared.mesh().vertex_count();
    if (Status s = Reserve(lane, frame, vertices); !s.ok()) return s;
    SkinKernelArgs args =
        KernelArgs(prepared, frame.method, lane.palette.get(), lane.out_positions.get(),
                   frame.device.normals ? lane.out_normals.get() : nullptr,
                   frame.device.tangents ? lane.out_tangents.get() : nullptr);
    if (Status s = Morph(lane, prepared, frame, &args, kernels, transfers); !s.ok()) return s;
    std::memcpy(slot, frame.palette.data(), frame.palette.size_bytes());
    if (cl_int err =
            clEnqueueWriteBuffer(lane.compute, lane.palette.get(), CL_FALSE, 0,
                                 frame.palette.size_bytes(), slot, 0, nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    if (Status s = runtime().EnqueueSkin(lane, prepared.mesh(), args, 0, vertices, kernels.Next());
        !s.ok()) {
      return s;
    }
    return out.Enqueue(frame, Float32DevicePieces(args, vertices, frame.device), transfers);
  }

  // The lane's device buffers (and pinned staging) large enough for `frame`.
  Status Reserve(OpenClLane& lane, const SkinFrame& frame, uint32_t vertex_count) {
    const std::size_t out_bytes = 3ull * vertex_count * sizeof(float);
    if (Status s = runtime().GrowBuffer("palette", CL_MEM_READ_ONLY, frame.palette.size_bytes(),
                                        &lane.palette, &lane.palette_bytes);
        !s.ok()) {
      return s;
    }
    if (Status s = GrowLaneOutputs(lane, frame, vertex_count); !s.ok()) return s;
    if (!runtime().staging()) return Status::Ok();
    if (Status s = runtime().GrowPinned(lane.compute, "pinned palette", frame.palette.size_bytes(),
                                        &lane.pinned_palette);
        !s.ok()) {
      return s;
    }
    // Encoded frames read back through the encoder's own pinned buffers; device frames
    // (GPU regions) read nothing back.
    if (frame.encoded.active() || frame.device.active()) return Status::Ok();
    if (Status s = runtime().GrowPinned(lane.compute, "pinned positions", out_bytes,
                                        &lane.pinned_positions);
        !s.ok()) {
      return s;
    }
    if (!frame.normals.empty()) {
      if (Status s =
              runtime().GrowPinned(lane.compute, "pinned normals", out_bytes, &lane.pinned_normals);
          !s.ok()) {
        return s;
      }
    }
    if (!frame.tangents.empty()) {
      return runtime().GrowPinned(lane.compute, "pinned tangents", frame.tangents.size_bytes(),
                                  &lane.pinned_tangents);
    }
    return Status::Ok();
  }

  // A frame with an active target: its weights written to the lane and the morph kernel
  // enqueued, both on the compute queue ahead of the skinning, which then reads the lane's
  // morphed rest arrays (`args` points at them). Other frames: nothing.
  Status Morph(OpenClLane& lane, const OpenClPreparedMesh& prepared, const SkinFrame& frame,
               SkinKernelArgs* args, ClEvents& kernels, ClEvents& transfers) {
    if (!MorphsOnDevice(frame, prepared.morph)) return Status::Ok();
    const std::size_t bytes = frame.morph_weights.size_bytes();
    if (Status s = runtime().GrowBuffer("morph weights", CL_MEM_READ_ONLY, bytes,
                                        &lane.morph_weights, &lane.morph_weights_bytes);
        !s.ok()) {
      return s;
    }
    // Non-blocking: the frame's weights, like its palette, are in use only within Skin(),
    // which waits for the whole frame (or, after an error, for the lane's queues).
    if (cl_int err =
            clEnqueueWriteBuffer(lane.compute, lane.morph_weights.get(), CL_FALSE, 0, bytes,
                                 frame.morph_weights.data(), 0, nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(morph weights)", err);
    }
    return EnqueueFrameMorph(runtime(), lane, prepared.mesh(), prepared.morph,
                             lane.morph_weights.get(), frame, args, kernels);
  }

  // One in-order queue: write, run, read in sequence; the last read blocks, so the
  // caller's palette and outputs are in use only within this call.
  Status SkinDirect(OpenClLane& lane, const OpenClPreparedMesh& prepared, const SkinFrame& frame,
                    const SkinKernelArgs& args, ClEvents& kernels, ClEvents& transfers) {
    const bool with_normals = !frame.normals.empty();
    if (Status s = EnqueueWholeFrame(lane, prepared, frame, args, kernels, transfers); !s.ok()) {
      return s;
    }
    if (with_normals) {
      if (cl_int err = clEnqueueReadBuffer(lane.compute, lane.out_normals.get(), CL_FALSE, 0,
                                           frame.normals.size_bytes(), frame.normals.data(), 0,
                                           nullptr, transfers.Next());
          err != CL_SUCCESS) {
        return ClError("clEnqueueReadBuffer(normals)", err);
      }
    }
    if (!frame.tangents.empty()) {
      if (cl_int err = clEnqueueReadBuffer(lane.compute, lane.out_tangents.get(), CL_FALSE, 0,
                                           frame.tangents.size_bytes(), frame.tangents.data(), 0,
                                           nullptr, transfers.Next());
          err != CL_SUCCESS) {
        return ClError("clEnqueueReadBuffer(tangents)", err);
      }
    }
    if (cl_int err = clEnqueueReadBuffer(lane.compute, lane.out_positions.get(), CL_TRUE, 0,
                                         frame.positions.size_bytes(), frame.positions.data(), 0,
                                         nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueReadBuffer(positions)", err);
    }
    return Status::Ok();
  }

  // Encoded output: the palette in, the whole frame's kernel, then the encoder's kernels
  // on the same queue and only the encoded bytes back (opencl_encode.h).
  Status SkinEncoded(OpenClLane& lane, const OpenClPreparedMesh& prepared, const SkinFrame& frame,
                     const SkinKernelArgs& args, ClEvents& kernels, ClEvents& transfers) {
    if (Status s = EnqueueWholeFrame(lane, prepared, frame, args, kernels, transfers); !s.ok()) {
      return s;
    }
    return encoder().Encode(lane, args, prepared.mesh().vertex_count(), frame,
                            /*zero_copy=*/false, kernels, transfers);
  }

  // On the compute queue: the palette in (through the lane's pinned memory when the
  // runtime stages), then the whole frame's kernel - the direct and the encoded paths.
  Status EnqueueWholeFrame(OpenClLane& lane, const OpenClPreparedMesh& prepared,
                           const SkinFrame& frame, const SkinKernelArgs& args, ClEvents& kernels,
                           ClEvents& transfers) {
    const void* palette = frame.palette.data();
    if (runtime().staging()) {
      std::memcpy(lane.pinned_palette.host, frame.palette.data(), frame.palette.size_bytes());
      palette = lane.pinned_palette.host;
    }
    if (cl_int err =
            clEnqueueWriteBuffer(lane.compute, lane.palette.get(), CL_FALSE, 0,
                                 frame.palette.size_bytes(), palette, 0, nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    const Mesh& mesh = prepared.mesh();
    return runtime().EnqueueSkin(lane, mesh, args, 0, mesh.vertex_count(), kernels.Next());
  }

  // Pinned staging, chunks, two queues: see the top of this file.
  Status SkinStaged(OpenClLane& lane, int copy_threads, const OpenClPreparedMesh& prepared,
                    const SkinFrame& frame, const SkinKernelArgs& args, ClEvents& kernels,
                    ClEvents& transfers) {
    const Mesh& mesh = prepared.mesh();
    const uint32_t vertices = mesh.vertex_count();
    std::memcpy(lane.pinned_palette.host, frame.palette.data(), frame.palette.size_bytes());
    if (cl_int err = clEnqueueWriteBuffer(lane.compute, lane.palette.get(), CL_FALSE, 0,
                                          frame.palette.size_bytes(), lane.pinned_palette.host, 0,
                                          nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    // The frame's outputs: each read back chunk by chunk into its pinned buffer, then copied
    // out to the caller's array.
    struct Output {
      const char* what;
      cl_mem from;
      void* pinned;
      float* to;
      std::size_t floats_per_vertex;
    };
    std::vector<Output> outputs = {{"clEnqueueReadBuffer(positions)", lane.out_positions.get(),
                                    lane.pinned_positions.host, frame.positions.data(), 3}};
    if (!frame.normals.empty()) {
      outputs.push_back({"clEnqueueReadBuffer(normals)", lane.out_normals.get(),
                         lane.pinned_normals.host, frame.normals.data(), 3});
    }
    if (!frame.tangents.empty()) {
      outputs.push_back({"clEnqueueReadBuffer(tangents)", lane.out_tangents.get(),
                         lane.pinned_tangents.host, frame.tangents.data(), 4});
    }
    const uint32_t align = OpenClRuntime::kChunkAlignment;
    const uint32_t most = static_cast<uint32_t>(runtime().max_chunks());
    // Chunks start at multiples of `align` (the runtime rounds min_chunk_vertices up too).
    const uint32_t per_chunk = std::max(runtime().min_chunk_vertices(),
                                        ((vertices + most - 1) / most + align - 1) / align * align);
    struct Chunk {
      uint32_t first, end;
      std::vector<cl_event> reads;
    };
    std::vector<Chunk> chunks;
    for (uint32_t first = 0; first < vertices; first += per_chunk) {
      Chunk chunk{first, std::min(vertices, first + per_chunk), {}};
      cl_event* kernel = kernels.Next();
      if (Status s = runtime().EnqueueSkin(lane, mesh, args, chunk.first, chunk.end, kernel);
          !s.ok()) {
        return s;
      }
      for (const Output& out : outputs) {
        const std::size_t offset = out.floats_per_vertex * chunk.first * sizeof(float),
                          bytes = out.floats_per_vertex * (chunk.end - chunk.first) * sizeof(float);
        cl_event* event = transfers.Next();
        if (cl_int err =
                clEnqueueReadBuffer(lane.transfer, out.from, CL_FALSE, offset, bytes,
                                    static_cast<char*>(out.pinned) + offset, 1, kernel, event);
            err != CL_SUCCESS) {
          return ClError(out.what, err);
        }
        chunk.reads.push_back(*event);
      }
      chunks.push_back(std::move(chunk));
      // Submit now, so the device starts on this chunk while the next is enqueued.
      clFlush(lane.compute);
      clFlush(lane.transfer);
    }
    for (const Chunk& chunk : chunks) {
      if (cl_int err =
              clWaitForEvents(static_cast<cl_uint>(chunk.reads.size()), chunk.reads.data());
          err != CL_SUCCESS) {
        return ClError("clWaitForEvents(read-back)", err);
      }
      for (const Output& out : outputs) {
        const std::size_t offset = out.floats_per_vertex * chunk.first * sizeof(float),
                          bytes = out.floats_per_vertex * (chunk.end - chunk.first) * sizeof(float);
        ParallelCopy(reinterpret_cast<char*>(out.to) + offset,
                     static_cast<const char*>(out.pinned) + offset, bytes, copy_threads);
      }
    }
    return Status::Ok();
  }
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                               std::shared_ptr<OpenClEncoder> encoder) {
  return std::make_unique<OpenClCopyBackend>(std::move(runtime), std::move(encoder));
}

}  // namespace skinserve
