// FrameJob: one frame on its way through the server, reused frame after frame by its
// stream so that the steady state allocates nothing of its own. It owns the palette the
// engine reads and one wire buffer that holds the answer as it goes on the wire: the
// vertex data of every part (each at most 1 MiB, so no message needs more than gRPC's
// default 4 MiB) and each part's serialized header. float32 frames are skinned straight
// into it; the other encodings are skinned into a float buffer and each instance is
// encoded into it on the compute thread that skinned it (OnInstanceSkinned). The parts go
// to gRPC as slices over that buffer: gRPC copies nothing, the kernel's socket copy is the
// only one. While gRPC holds those slices the buffer must not change: wire_in_use() tells,
// and the listener is held until gRPC lets go. All buffers grow to the largest frame seen
// and are charged to the in-flight budget until the job is destroyed (its stream ends).
// A frame that names a shared-memory region (SkinRequest.output) is skinned (float32) or
// encoded straight into the region instead, and its answer is one part of header only.
#pragma once

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/slice.h>

#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "frames/inflight_budget.h"
#include "frames/pose_request.h"
#include "frames/stream_plan.h"
#include "gpu/gpu_region_registry.h"
#include "observability/metrics_frames.h"
#include "rpc/stream_answer.h"
#include "shm/mapped_region.h"
#include "shm/region_handle.h"
#include "shm/region_registry.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/engine/engine.h"
#include "skinserve/model/aligned_buffer.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

class FrameJob final : public SkinJob, public StreamAnswer {
 public:
  // Told on a compute thread once the answer is ready (or failed): a FrameJob's, or a
  // TickJob's (which listens to its characters' FrameJobs and tells its own listener).
  class Listener {
   public:
    virtual void OnFrameDone(StreamAnswer* job) = 0;
    // SkinRequest.early_parts (and ticks, as characters finish): more of the answer's parts
    // may go out (HasPartToSend), on a compute thread, before OnFrameDone.
    virtual void OnPartsReady(StreamAnswer* job) = 0;
    // The listener stays alive from HoldForWire (the first part handed out) until
    // ReleaseForWire (gRPC dropped the last slice of the job's wire buffer). Release may
    // come on any thread, also from inside the listener's own calls into gRPC while it
    // holds its lock: it must not lock.
    virtual void HoldForWire() = 0;
    virtual void ReleaseForWire() = 0;

   protected:
    ~Listener() = default;
  };

  FrameJob(Listener* listener, InflightBudget* budget) : listener_(listener), budget_(budget) {}
  ~FrameJob() override;

  // Prepares `request` for the engine: plans it with the stream's `plan` (built when its
  // settings change, else reused: stream_plan.h), pins the output region and checks the
  // frame's range in it, charges the buffers to the budget, takes the frame's inputs
  // (morph weights; the palette's bytes, swapped out of `request` so that they are not
  // copied again; a pose checked, to be evaluated on the compute thread) and points the outputs at
  // the wire buffer or the region. Then Engine::Run(this). Non-OK: the frame failed before the
  // engine. `regions.regions` is null when shared memory is off.
  Status Prepare(v1::SkinRequest& request, Engine& engine, const std::string& default_backend,
                 const RegionCaller& regions, StreamPlan* plan);
  // The frame failed before the engine: it is answered with `status`.
  void Fail(Status status);
  // A frame refused before its request was parsed (SkinRequestReader): answered with
  // `status` under the frame number the reader's scan found.
  void Refuse(uint64_t frame, const std::string& backend, Status status);

  bool done() const override { return done_; }  // under the listener's lock
  void set_done() override { done_ = true; }
  const Status& status() const override { return result_; }
  uint64_t frame() const { return frame_; }
  // Whether a part is ready to go out that was not handed out yet.
  bool HasPartToSend() override;
  // The next response part, serialized; nullptr while none is ready (every part handed
  // out, or the rest not skinned yet). `*last` tells whether it is the frame's final
  // part (in a tick: the character's). Valid until PartWritten or the next call.
  const grpc::ByteBuffer* NextPart(bool* last) override;
  // The part handed out last was written (or failed): the job lets go of it.
  void PartWritten() override { out_.reset(); }
  // Lets go of every slice the job itself still holds (a frame abandoned mid-way).
  void DropWire() override;
  // Whether gRPC still holds slices of the wire buffer: until then the job is not reused.
  bool wire_in_use() const override { return wire_refs_.load(std::memory_order_acquire) > 0; }

  // Tick mode (TickJob, frame_job_tick.cpp): the job is character `character` of tick
  // `frame` (its request's own frame field is ignored): every part carries the character,
  // its vertex parts have `last` false, and a region character's answer is its TickHeader.
  void SetTickCharacter(uint32_t character, uint64_t frame);
  int64_t tick_character() const { return tick_character_; }  // -1: a plain frame
  // The character's header in the tick's TickAnswer, once it is done (or failed): as its
  // final part would be without vertex data; a failure's message names the character.
  void TickHeader(v1::SkinResponse* out) const;
  // The answer is in a shared-memory region (no vertex parts of its own).
  bool answers_in_region() const { return region_part_; }
  // A character written into a GPU region keeps the region until the tick has signalled
  // it (TickJob): handed over here, once the character is done (null: none).
  std::shared_ptr<GpuRegion> TakeGpuRegion() { return std::move(gpu_region_); }
  // The character is skinned, but the tick could not signal its GPU region: it fails.
  void FailWritten(Status status) { result_ = std::move(status); }

 private:
  // Encodes instance `instance` into the wire buffer, on the thread that skinned it.
  Status OnInstanceSkinned(uint32_t instance, std::span<const float> positions,
                           std::span<const float> normals) override;
  void OnSkinned(Status status, const FrameTiming& timing) override;
  // A pose frame's palette (request.fill_inputs_on_run), on the thread that skins it.
  Status FillInputs() override;
  // Resets the job for frame `frame` (its metrics record begins now).
  Status Begin(uint64_t frame, const std::string& backend);
  Status EncodeInstance(uint32_t i, std::span<const float> positions,
                        std::span<const float> normals);
  // Prepare's steps. The plan's layout, copied: a later frame may change the plan while
  // this one is in flight.
  void ApplyLayout(const FrameLayout& layout);
  // Where the frame lies in its region from the request's output.offset, which must be a
  // multiple of wire::kRegionAlignment (INVALID_ARGUMENT naming it): each frame's own, since
  // the offset is no part of the plan's key.
  Status PlaceInRegion(const v1::OutputRegion& output);
  // Resolves the request's region through the stream's handle, checks the frame's range
  // against it and pins it.
  Status PinRegion(const v1::OutputRegion& output, const RegionCaller& regions,
                   RegionHandle* handle);
  // Checks the laid-out frame's range (region_end_) against a region of `size` bytes and
  // the request's output.byte_size.
  Status CheckRegionRange(const v1::OutputRegion& output, uint64_t size) const;
  // The same for a GPU region (output.gpu, gpu/gpu_frame_output.cpp); pins it.
  Status PinGpuRegion(const v1::OutputRegion& output, const RegionCaller& regions);
  // Charges what the frame holds to the in-flight budget and grows the buffers.
  Status ChargeBuffers(std::size_t palette_bytes);
  // The morph weights and the palette, into the engine's request.
  Status TakeInputs(v1::SkinRequest& wire, Engine& engine);
  // The engine's outputs: the wire buffer, the region, the job's floats or scratch.
  void SetOutputs();
  // request.device: the frame's layout in the GPU region (SetOutputs emptied the others).
  void SetGpuOutput();
  // After the frame: FAILED_PRECONDITION if the GPU region was unregistered meanwhile;
  // else a plain frame signals the region's semaphore (a tick's character leaves that to
  // the tick).
  Status GpuRegionStillThere();
  // The frame's output: the wire buffer, or the region's bytes.
  std::byte* PositionsOut();
  std::byte* NormalsOut();
  std::byte* TangentsOut();
  // Once every instance is in the wire buffer: each part's header, with the timings.
  Status WriteHeaders();
  Status WriteRegionHeader();  // the one part of a frame written into a region
  // The fields every part of the frame shares, with the timings or (early parts) without.
  void SetCommonHeader(bool with_timing);
  Status WritePartHeader(std::size_t part);
  // early_parts: instance `instance` is in the wire buffer; releases the parts that the
  // instances done in order cover (never the final one) and tells the listener.
  Status MarkInstanceReady(uint32_t instance);
  void SetErrorPart();
  static void WireReleased(void* job);  // gRPC dropped the last slice

  Listener* const listener_;
  InflightBudget* const budget_;
  uint64_t charged_ = 0;  // bytes of this job's buffers charged to the budget

  uint32_t vertices_ = 0;  // per instance: the planned mesh's
  uint64_t frame_ = 0;
  uint32_t instances_ = 1;
  bool want_normals_ = false;
  bool want_tangents_ = false;  // x y z w per vertex, after the normals
  VertexEncoding encoding_ = VertexEncoding::kFloat32;
  bool boxed_ = false;           // each instance's box travels with it (snorm16)
  bool device_encoded_ = false;  // the backend writes the encoding (BackendInfo.encoded_outputs)
  bool box_scratch_ = false;     // ...snorm16 on the host: positions_ is its box_scratch
  FrameLayout layout_;           // the plan's, for the frame in flight
  // The palette's bytes as parsed (the engine reads them in place), swapped with the
  // request's string every frame; palette_ only if they were ever misaligned for floats.
  std::string palette_bytes_;
  std::vector<float> palette_;
  PoseEvaluator pose_;              // turns SkinRequest.pose into palette_ (FillInputs)
  std::vector<MorphWeight> morph_;  // the frame's morph weights, capacity reused
  // A crowd's per-instance morph weights, back to back, and one view per instance.
  std::vector<MorphWeight> instance_morph_;
  std::vector<std::span<const MorphWeight>> instance_morph_views_;
  // Skinned floats for encodings other than float32, for instances too large for the
  // compute thread's scratch (SkinRequest::skin_into_scratch); positions_ is also the
  // box_scratch of snorm16 written by a host backend (EncodedOutput::box_scratch).
  std::vector<float> positions_;
  std::vector<float> normals_;
  std::vector<float> tangents_;  // every encoding but float32 (never skinned into scratch)
  std::vector<Bounds> bounds_;   // each instance's box, for boxed encodings

  // Frames into a shared-memory region: the region, pinned from Prepare until the frame
  // is done, and where in it positions and normals go.
  std::shared_ptr<MappedRegion> region_;
  bool region_part_ = false;  // the answer is one header-only part (RegionWrite)
  uint64_t region_positions_ = 0, region_normals_ = 0, region_tangents_ = 0, region_end_ = 0;
  // Frames into a GPU region (output.gpu): pinned likewise; the layout as above.
  std::shared_ptr<GpuRegion> gpu_region_;

  // Part p's header sits at headers_offset_ + p * header_room_ in wire_: the serialized
  // header with the positions field's tag and length, then the normals field's.
  struct PartHeader {
    std::size_t size = 0;               // up to and with the positions field's tag and length
    std::size_t normals_tag_size = 0;   // 0 without normals
    std::size_t tangents_tag_size = 0;  // 0 without tangents
  };
  // Vertices [first, first + count) of instances [instance, instance + instances): one
  // instance's range, or several whole ones (packed).
  struct PartRange {
    uint32_t instance = 0, first = 0, count = 0, instances = 1;
  };
  PartRange RangeOf(std::size_t part) const;
  std::vector<PartHeader> headers_;
  AlignedBuffer<std::byte> wire_;
  // wire_: positions from 0, normals, tangents, then the headers.
  std::size_t normals_offset_ = 0, tangents_offset_ = 0, headers_offset_ = 0, header_room_ = 0,
              wire_used_ = 0;
  v1::SkinResponse header_;              // reused to serialize each part's header
  std::atomic<int> wire_refs_{0};        // 1 while gRPC or the job holds slices of wire_
  grpc::Slice wire_slice_;               // over wire_[0, wire_used_), while parts are handed out
  std::optional<grpc::ByteBuffer> out_;  // the part handed out last
  bool error_part_ = false;              // the answer is one error part: error_bytes_
  grpc::ByteBuffer error_bytes_;

  std::size_t part_count_ = 0;
  uint32_t vertices_per_part_ = 1;  // at most 1 MiB of encoded vertex data per part
  std::size_t parts_per_instance_ = 1;
  uint32_t instances_per_part_ = 1;    // > 1: packed parts (SkinRequest.pack_instances)
  std::atomic<int64_t> encode_ns_{0};  // summed over instances (they may run in parallel)
  std::size_t next_part_ = 0;
  // SkinRequest.early_parts: instances encoded so far (any order), how many lead without a
  // gap, and the parts whose headers are written and may go out (all of them otherwise,
  // once the frame is done). parts_mutex_ guards the parts' hand-out state against the
  // compute threads that release early parts and fail frames.
  bool early_ = false;
  std::vector<uint8_t> instance_ready_;
  uint32_t ready_instances_ = 0;
  std::atomic<std::size_t> parts_ready_{0};
  std::mutex parts_mutex_;
  Status result_;
  FrameTiming timing_;
  bool done_ = false;
  FrameRecord record_;  // for the metrics
  // Tick mode: the character's index (-1: a plain frame) and the tick's frame number.
  int64_t tick_character_ = -1;
  uint64_t tick_frame_ = 0;
};

}  // namespace skinserve::server
