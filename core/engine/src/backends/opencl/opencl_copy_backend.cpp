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
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <vector>

#include "backends/opencl/opencl_backend_base.h"
#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_device_memory.h"
#include "backends/opencl/opencl_mesh_arena.h"
#include "backends/opencl/opencl_tick_launch.h"

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

// `info` saying that SkinFrames skins host frames together (OpenClCopyBackend::SkinFrames),
// and where GPU regions are written in place (DirectFloat32Outputs).
BackendInfo CopyBackendInfo(BackendInfo info, const OpenClRuntime& runtime) {
  info.skins_frames_together = true;
  info.description +=
      fmt::format("; GPU regions written in place at offsets that are multiples of {} bytes",
                  runtime.base_address_alignment());
  return info;
}

class OpenClCopyBackend final : public OpenClBackendBase {
 public:
  OpenClCopyBackend(const std::shared_ptr<OpenClRuntime>& runtime,
                    std::shared_ptr<OpenClEncoder> encoder)
      : OpenClBackendBase(
            runtime, std::move(encoder), CL_MEM_COPY_HOST_PTR,
            CopyBackendInfo(
                OpenClBackendInfo(
                    *runtime, "opencl",
                    runtime->staging()
                        ? "OpenCL kernel; palette written and result read back per frame "
                          "through pinned memory, in overlapped chunks"
                        : "OpenCL kernel; palette written and result read back per frame",
                    // Staged: a frame waits on the device and then copies with the threads other
                    // frames leave free, so it holds one compute thread of the engine.
                    runtime->staging() ? 1 : runtime->compute_units()),
                *runtime),
            OpenClMeshArena::Create(runtime, runtime->mesh_arena_bytes())) {}

  // GPU regions: only this backend imports device memory (opencl_device_memory.h).
  Result<std::shared_ptr<DeviceMemory>> ImportDeviceMemory(
      const DeviceMemoryImport& import) override {
    return ImportOpenClDeviceMemory(runtime(), info().id, import);
  }

  // A tick's characters, skinned together on one lane. Those that can run in tick
  // launches (opencl_tick_launch.h: linear float32 meshes of the arena, no morph) do, a
  // few launches for all of them; the others as follows. Frames into GPU regions (float32):
  // enqueued one after another (each its palette from a slot of its own, its kernel into
  // the lane's buffers, which the in-order queue reuses safely, its copies into the
  // memory), then one wait for all of them. Frames into host memory (float32): enqueued the
  // same way with their read-backs (into pinned memory of the batch when the runtime
  // stages, else straight into the frame's arrays), then copied out one by one as each
  // read completes, while the device works on the later ones: a lane, a wait and a start
  // per character become one per batch. Encoded frames, and host frames larger than a
  // batch's pinned memory, run as Skin does, first.
  void SkinFrames(std::span<const PreparedMesh* const> prepared, std::span<const SkinFrame> frames,
                  std::span<Status> statuses) override {
    std::vector<Together> how(frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
      how[i] = HowTogether(frames[i]);
      // Before this batch holds a lane (a device sharing host memory has one) or a
      // memory's lock.
      if (how[i] == Together::kAlone) statuses[i] = Skin(*prepared[i], frames[i]);
    }
    auto lane = runtime().AcquireLane();
    const std::size_t slot_bytes = PaletteSlotBytes(frames);
    std::vector<std::byte> host_slots;  // a device sharing host memory: no pinned staging
    std::byte* slots = PaletteSlots(*lane, slot_bytes * frames.size(), &host_slots);
    if (slots == nullptr) {
      const Status s = ClError("the batch's pinned palettes", CL_OUT_OF_HOST_MEMORY);
      for (std::size_t i = 0; i < frames.size(); ++i) {
        if (how[i] != Together::kAlone) statuses[i] = s;
      }
      return;
    }
    // Declared before `out`, whose Finish (or destruction) waits for what it enqueued.
    OpenClTickLaunches ticks(runtime(), *lane);
    DeviceOutputBatch out(*lane);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const auto& mesh = static_cast<const OpenClPreparedMesh&>(*prepared[i]);
      if (how[i] == Together::kAlone || !OpenClTickLaunches::Takes(runtime(), mesh, frames[i])) {
        continue;
      }
      how[i] = Together::kTick;
      statuses[i] = InKernelLayout(mesh, frames[i], [&](const auto& m, const auto&) {
        ticks.Add(i, m, frames[i]);  // a linear float32 frame: its palette as it came
        return Status::Ok();
      });
    }
    ticks.Run(out, statuses);
    std::deque<ClEvents> kernels(frames.size()), transfers(frames.size());
    std::vector<std::size_t> enqueued;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (how[i] != Together::kDevice) continue;
      statuses[i] = InKernelLayout(*prepared[i], frames[i], [&](const auto& mesh, const auto& f) {
        return EnqueueDeviceFrame(*lane, mesh, f, slots + i * slot_bytes, out, kernels[i],
                                  transfers[i]);
      });
      if (statuses[i].ok()) enqueued.push_back(i);
    }
    SkinHostFrames(*lane, prepared, frames, how, slots, slot_bytes, kernels, transfers, statuses);
    const Status finished = out.Finish();
    ticks.FinishDevice(finished, statuses);
    for (std::size_t i : enqueued) {
      statuses[i] = finished.ok()
                        ? RecordDeviceTiming(kernels[i], transfers[i], runtime().device_timing(),
                                             frames[i].device_timing)
                        : finished;
    }
  }

 private:
  // How SkinFrames skins a frame.
  enum class Together { kAlone, kDevice, kHost, kTick };

  // A batch's pinned memory for read-backs holds at most this much; larger frames run
  // alone (Skin: chunks whose reads overlap their kernels, which pays at that size).
  static constexpr std::size_t kMaxBatchOutputBytes = std::size_t{64} << 20;

  static std::size_t HostOutputBytes(const SkinFrame& frame) {
    return frame.positions.size_bytes() + frame.normals.size_bytes() + frame.tangents.size_bytes();
  }

  Together HowTogether(const SkinFrame& frame) const {
    if (frame.device.active()) {
      // Encoded frames wait for their flag and box anyway.
      return frame.device.encoding == VertexEncoding::kFloat32 ? Together::kDevice
                                                               : Together::kAlone;
    }
    if (frame.encoded.active()) return Together::kAlone;
    return HostOutputBytes(frame) <= kMaxBatchOutputBytes ? Together::kHost : Together::kAlone;
  }

  // `bytes` of palette slots: the lane's pinned ones when the runtime stages, else
  // `*host`'s; null when the pinned memory cannot grow.
  std::byte* PaletteSlots(OpenClLane& lane, std::size_t bytes, std::vector<std::byte>* host) {
    if (!runtime().staging()) {
      host->resize(bytes);
      return host->data();
    }
    if (!runtime()
             .GrowPinned(lane.compute, "pinned batch palettes", bytes, &lane.pinned_batch_palettes)
             .ok()) {
      return nullptr;
    }
    return static_cast<std::byte*>(lane.pinned_batch_palettes.host);
  }

  // SkinFrames' host frames, in groups whose read-backs fit kMaxBatchOutputBytes: each
  // group enqueued, then drained in order (a frame's last read waited for, its outputs
  // copied out of pinned memory), so the device skins frame k + 1 while frame k is copied.
  void SkinHostFrames(OpenClLane& lane, std::span<const PreparedMesh* const> prepared,
                      std::span<const SkinFrame> frames, std::span<const Together> how,
                      std::byte* slots, std::size_t slot_bytes, std::deque<ClEvents>& kernels,
                      std::deque<ClEvents>& transfers, std::span<Status> statuses) {
    std::vector<std::size_t> group;
    std::size_t group_bytes = 0;
    const auto run_group = [&] {
      if (group.empty()) return;
      // Sized once for the whole group: growing it would move reads already enqueued.
      if (runtime().staging()) {
        if (Status s = runtime().GrowPinned(lane.compute, "pinned batch outputs", group_bytes,
                                            &lane.pinned_batch_outputs);
            !s.ok()) {
          for (std::size_t i : group) statuses[i] = s;
          group.clear();
        }
      }
      std::vector<HostRead> reads;
      std::size_t offset = 0;
      for (std::size_t i : group) {
        std::byte* pinned = runtime().staging()
                                ? static_cast<std::byte*>(lane.pinned_batch_outputs.host) + offset
                                : nullptr;
        offset += HostOutputBytes(frames[i]);
        cl_event last = nullptr;
        statuses[i] = InKernelLayout(*prepared[i], frames[i], [&](const auto& mesh, const auto& f) {
          return EnqueueHostFrame(lane, mesh, f, slots + i * slot_bytes, pinned, kernels[i],
                                  transfers[i], &last);
        });
        if (statuses[i].ok()) reads.push_back({i, pinned, last});
      }
      DrainHostFrames(lane, frames, reads, kernels, transfers, statuses);
      group.clear();
      group_bytes = 0;
    };
    for (std::size_t i = 0; i < frames.size(); ++i) {
      if (how[i] != Together::kHost) continue;
      const std::size_t bytes = HostOutputBytes(frames[i]);
      if (group_bytes + bytes > kMaxBatchOutputBytes) run_group();
      group.push_back(i);
      group_bytes += bytes;
    }
    run_group();
  }

  // A host frame of SkinFrames once enqueued: where its outputs arrive (pinned: the
  // batch's pinned memory, else null: the frame's own arrays) and its last read.
  struct HostRead {
    std::size_t frame;
    std::byte* pinned;
    cl_event last;  // owned by the frame's transfer events
  };

  // Waits for each of `reads` in order and copies its outputs out of pinned memory. After
  // a failed wait, that frame and the later ones fail with it, once the lane is idle.
  void DrainHostFrames(OpenClLane& lane, std::span<const SkinFrame> frames,
                       std::span<const HostRead> reads, std::deque<ClEvents>& kernels,
                       std::deque<ClEvents>& transfers, std::span<Status> statuses) {
    clFlush(lane.compute);
    Status failed;
    for (const HostRead& read : reads) {
      const SkinFrame& frame = frames[read.frame];
      if (failed.ok()) {
        if (cl_int err = clWaitForEvents(1, &read.last); err != CL_SUCCESS) {
          failed = ClError("clWaitForEvents(read-back)", err);
          clFinish(lane.compute);  // nothing of the batch still runs into its memory
        }
      }
      if (!failed.ok()) {
        statuses[read.frame] = failed;
        continue;
      }
      if (read.pinned != nullptr) {
        std::size_t offset = 0;
        for (std::span<float> to : {frame.positions, frame.normals, frame.tangents}) {
          if (to.empty()) continue;  // (memcpy takes no null pointer, even for 0 bytes)
          std::memcpy(to.data(), read.pinned + offset, to.size_bytes());
          offset += to.size_bytes();
        }
      }
      statuses[read.frame] = RecordDeviceTiming(kernels[read.frame], transfers[read.frame],
                                                runtime().device_timing(), frame.device_timing);
    }
  }

  // One host frame of a batch, enqueued on `lane`'s compute queue without a wait: its morph
  // (if any), its palette (copied into `slot`, the frame's until the batch's wait), its
  // kernel into the lane's buffers, its reads into `pinned` (positions, normals, tangents
  // one after another) or, null, into the frame's arrays; *last is the last read's event.
  Status EnqueueHostFrame(OpenClLane& lane, const OpenClPreparedMesh& prepared,
                          const SkinFrame& frame, std::byte* slot, std::byte* pinned,
                          ClEvents& kernels, ClEvents& transfers, cl_event* last) {
    const uint32_t vertices = prepared.mesh().vertex_count();
    if (Status s = ReserveDeviceBuffers(lane, frame, vertices); !s.ok()) return s;
    SkinKernelArgs args =
        KernelArgs(prepared, frame.method, lane.palette.get(), lane.out_positions.get(),
                   frame.wants_normals() ? lane.out_normals.get() : nullptr,
                   frame.wants_tangents() ? lane.out_tangents.get() : nullptr);
    if (Status s = Morph(lane, prepared, frame, &args, kernels, transfers); !s.ok()) return s;
    if (Status s = EnqueuePaletteFromSlot(lane, frame, slot, transfers); !s.ok()) return s;
    if (Status s = runtime().EnqueueSkin(lane, prepared.mesh(), args, 0, vertices, kernels.Next());
        !s.ok()) {
      return s;
    }
    const std::pair<cl_mem, std::span<float>> outputs[] = {{args.out_positions, frame.positions},
                                                           {args.out_normals, frame.normals},
                                                           {args.out_tangents, frame.tangents}};
    std::size_t offset = 0;
    for (const auto& [from, to] : outputs) {
      if (to.empty()) continue;
      void* into = pinned != nullptr ? static_cast<void*>(pinned + offset) : to.data();
      offset += to.size_bytes();
      cl_event* event = transfers.Next();
      if (cl_int err = clEnqueueReadBuffer(lane.compute, from, CL_FALSE, 0, to.size_bytes(), into,
                                           0, nullptr, event);
          err != CL_SUCCESS) {
        return ClError("clEnqueueReadBuffer(batch output)", err);
      }
      *last = *event;
    }
    clFlush(lane.compute);  // the device starts on this frame while the next is enqueued
    return Status::Ok();
  }

  // The frame's palette written to the lane's buffer from `slot` (a batch's, the frame's
  // until the batch's wait).
  Status EnqueuePaletteFromSlot(OpenClLane& lane, const SkinFrame& frame, std::byte* slot,
                                ClEvents& transfers) {
    std::memcpy(slot, frame.palette.data(), frame.palette.size_bytes());
    if (cl_int err =
            clEnqueueWriteBuffer(lane.compute, lane.palette.get(), CL_FALSE, 0,
                                 frame.palette.size_bytes(), slot, 0, nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    return Status::Ok();
  }

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
    if (status.ok() && frame.device.active() &&
        frame.device.encoding == VertexEncoding::kFloat32) {  // a GPU region
      status = SkinIntoDevice(*lane, prepared, frame, args, kernels, transfers);
    } else if (status.ok() && frame.device.active()) {  // encoded into a GPU region
      status = EnqueueWholeFrame(*lane, prepared, frame, args, kernels, transfers);
      const uint32_t vertices = prepared.mesh().vertex_count();
      if (status.ok()) {
        status = encoder().EncodeIntoDevice(*lane, args, vertices, frame, kernels, transfers);
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
    return RecordDeviceTiming(kernels, transfers, runtime().device_timing(), frame.device_timing);
  }

  // A float32 frame into a GPU region (opencl_device_memory.h), waited for: the kernel
  // writes the memory in place where the frame's offsets allow (DirectFloat32Outputs),
  // else into the lane's buffers, which are then copied there.
  Status SkinIntoDevice(OpenClLane& lane, const OpenClPreparedMesh& prepared,
                        const SkinFrame& frame, const SkinKernelArgs& args, ClEvents& kernels,
                        ClEvents& transfers) {
    const uint32_t vertices = prepared.mesh().vertex_count();
    DeviceOutputBatch out(lane);
    Result<DirectDeviceOutputs> direct =
        DirectFloat32Outputs(frame, vertices, runtime().base_address_alignment());
    if (!direct.ok()) return direct.status();
    if (direct->active()) {
      if (Status s = out.Hold(frame, transfers); !s.ok()) return s;  // before the kernel
      if (Status s =
              EnqueueWholeFrame(lane, prepared, frame, InPlace(args, *direct), kernels, transfers);
          !s.ok()) {
        return s;
      }
      return out.Finish();
    }
    if (Status s = EnqueueWholeFrame(lane, prepared, frame, args, kernels, transfers); !s.ok()) {
      return s;
    }
    if (Status s = out.Enqueue(frame, Float32DevicePieces(args, vertices, frame.device), transfers);
        !s.ok()) {
      return s;
    }
    return out.Finish();
  }

  // `args` writing into `direct`'s sub-buffers instead of the lane's outputs.
  static SkinKernelArgs InPlace(SkinKernelArgs args, const DirectDeviceOutputs& direct) {
    args.out_positions = direct.positions.get();
    args.out_normals = direct.normals.get();
    args.out_tangents = direct.tangents.get();
    return args;
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
    Result<DirectDeviceOutputs> direct =
        DirectFloat32Outputs(frame, vertices, runtime().base_address_alignment());
    if (!direct.ok()) return direct.status();
    SkinKernelArgs args =
        KernelArgs(prepared, frame.method, lane.palette.get(), lane.out_positions.get(),
                   frame.device.normals ? lane.out_normals.get() : nullptr,
                   frame.device.tangents ? lane.out_tangents.get() : nullptr);
    if (Status s = Morph(lane, prepared, frame, &args, kernels, transfers); !s.ok()) return s;
    // In place: the memory is held (acquired) before the kernel that writes it; the
    // sub-buffers may go once the kernel is enqueued (it keeps them).
    if (direct->active()) {
      if (Status s = out.Hold(frame, transfers); !s.ok()) return s;
      args = InPlace(args, *direct);
    }
    if (Status s = EnqueuePaletteFromSlot(lane, frame, slot, transfers); !s.ok()) return s;
    if (Status s = runtime().EnqueueSkin(lane, prepared.mesh(), args, 0, vertices, kernels.Next());
        !s.ok()) {
      return s;
    }
    if (direct->active()) return Status::Ok();
    return out.Enqueue(frame, Float32DevicePieces(args, vertices, frame.device), transfers);
  }

  // The lane's device buffers large enough for `frame`: its palette and outputs.
  Status ReserveDeviceBuffers(OpenClLane& lane, const SkinFrame& frame, uint32_t vertex_count) {
    if (Status s = runtime().GrowBuffer("palette", CL_MEM_READ_ONLY, frame.palette.size_bytes(),
                                        &lane.palette, &lane.palette_bytes);
        !s.ok()) {
      return s;
    }
    return GrowLaneOutputs(lane, frame, vertex_count);
  }

  // The lane's device buffers (and pinned staging) large enough for `frame`.
  Status Reserve(OpenClLane& lane, const SkinFrame& frame, uint32_t vertex_count) {
    const std::size_t out_bytes = 3ull * vertex_count * sizeof(float);
    if (Status s = ReserveDeviceBuffers(lane, frame, vertex_count); !s.ok()) return s;
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
