#include "frames/frame_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include <grpcpp/impl/codegen/proto_utils.h>

#include "rpc/server_messages.h"
#include "skinserve/wire/part_framing.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::server {
namespace {

// Grows `buffer` to hold `count` values (never shrinks, so alternating sizes do not
// re-zero it) and returns the first `count`.
std::span<float> Reuse(std::vector<float>& buffer, std::size_t count) {
  if (buffer.size() < count) buffer.resize(count);
  return {buffer.data(), count};
}

// The palette's floats in `bytes` (little-endian float32, the wire's), read in place: a
// string's storage comes from operator new (aligned for any scalar) or, for fewer than 16
// bytes, sits inside the string object. Should it ever be misaligned for a float, the
// values are copied into `fallback` instead.
std::span<const float> PaletteFloats(const std::string& bytes, std::vector<float>* fallback) {
  const std::size_t count = bytes.size() / sizeof(float);
  if (reinterpret_cast<std::uintptr_t>(bytes.data()) % alignof(float) == 0) {
    return {reinterpret_cast<const float*>(bytes.data()), count};
  }
  fallback->resize(count);
  std::memcpy(fallback->data(), bytes.data(), count * sizeof(float));
  return *fallback;
}

Status InstanceError(const Status& status, uint32_t instance, uint32_t instances) {
  if (instances <= 1) return status;
  return Status(status.code(), fmt::format("instance {}: {}", instance, status.message()));
}

}  // namespace

FrameJob::~FrameJob() {
  DropWire();
  budget_->Release(charged_);
}

FrameJob::PartRange FrameJob::RangeOf(std::size_t part) const {
  PartRange r;
  if (instances_per_part_ > 1) {
    r.instance = static_cast<uint32_t>(part * instances_per_part_);
    r.count = vertices_;
    r.instances = std::min(instances_per_part_, instances_ - r.instance);
    return r;
  }
  r.instance = static_cast<uint32_t>(part / parts_per_instance_);
  r.first = static_cast<uint32_t>(part % parts_per_instance_) * vertices_per_part_;
  r.count = std::min(vertices_per_part_, vertices_ - r.first);
  return r;
}

Status FrameJob::Prepare(v1::SkinRequest& wire, Engine& engine, const std::string& default_backend,
                         const RegionCaller& regions, StreamPlan* plan) {
  const std::string& backend = wire.backend().empty() ? default_backend : wire.backend();
  if (Status s = Begin(wire.frame(), backend); !s.ok()) return s;
  // The stream's plan: checked and laid out once, reused while the settings stay (no
  // lookup); the mesh is pinned from here until the frame is done.
  if (Status s = plan->PlanFrame(wire, backend, engine, this); !s.ok()) return s;
  ApplyLayout(plan->layout());
  if (region_part_) {  // a GPU region (output.gpu) or a shared-memory one
    if (Status s = PlaceInRegion(wire.output()); !s.ok()) return s;
    if (Status s = wire.output().gpu() ? PinGpuRegion(wire.output(), regions)
                                       : PinRegion(wire.output(), regions, plan->region());
        !s.ok()) {
      return s;
    }
  }
  // A pose (SkinRequest.pose) is turned into a palette of the mesh's joints here.
  const uint64_t palette_bytes =
      wire.has_pose() ? 12ull * sizeof(float) * this->plan().joint_count : wire.palette().size();
  if (Status s = ChargeBuffers(palette_bytes); !s.ok()) return s;
  if (Status s = TakeInputs(wire, engine); !s.ok()) return s;
  SetOutputs();
  return Status::Ok();
}

void FrameJob::ApplyLayout(const FrameLayout& l) {
  layout_ = l;
  vertices_ = l.vertices;
  instances_ = l.instances;
  want_normals_ = l.want_normals;
  want_tangents_ = l.want_tangents;
  encoding_ = l.encoding;
  boxed_ = l.boxed;
  device_encoded_ = l.device_encoded;
  box_scratch_ = l.box_scratch;
  vertices_per_part_ = l.vertices_per_part;
  parts_per_instance_ = l.parts_per_instance;
  part_count_ = l.part_count;
  instances_per_part_ = l.instances_per_part;
  header_room_ = l.header_room;
  normals_offset_ = l.normals_offset;
  tangents_offset_ = l.tangents_offset;
  headers_offset_ = l.headers_offset;
  wire_used_ = l.wire_used;
  region_part_ = l.in_region;
  early_ = l.early;
  if (early_) instance_ready_.assign(instances_, 0);  // keeps its capacity
}

Status FrameJob::ChargeBuffers(std::size_t palette_bytes) {
  // What this frame holds while in flight; the job keeps its buffers, so only growth is
  // charged.
  const uint64_t need = palette_bytes + layout_.floats_kept + std::max(wire_used_, wire_.size());
  if (need > charged_) {
    if (Status s = budget_->TryCharge(need - charged_); !s.ok()) return s;
    charged_ = need;
  }
  encode_ns_.store(0);
  if (headers_.size() < part_count_) headers_.resize(part_count_);
  if (bounds_.size() < instances_) bounds_.resize(instances_);
  if (wire_.size() < wire_used_) wire_ = AlignedBuffer<std::byte>(wire_used_);
  return Status::Ok();
}

namespace {

// Dense weights (one per morph target) as a frame carries them: the non-zero ones.
void SparseMorphWeights(std::span<const float> dense, std::vector<MorphWeight>* out) {
  out->clear();
  for (std::size_t i = 0; i < dense.size(); ++i) {
    if (dense[i] != 0) out->push_back({.target = static_cast<uint32_t>(i), .weight = dense[i]});
  }
}

}  // namespace

Status FrameJob::TakeInputs(v1::SkinRequest& wire, Engine& engine) {
  if (Status s = MorphWeightsFromWire(wire, &morph_); !s.ok()) return s;
  request.morph_weights = morph_;  // checked against the mesh by the engine
  if (Status s = InstanceMorphWeightsFromWire(wire, &instance_morph_, &instance_morph_views_);
      !s.ok()) {
    return s;
  }
  request.instance_morph_weights = instance_morph_views_;
  // A pose is checked here and evaluated into palette_ on the compute thread that skins
  // the frame (FillInputs): a tick's poses spread over the threads with its skinning.
  request.fill_inputs_on_run = wire.has_pose();
  if (wire.has_pose()) {
    if (Status s =
            pose_.Check(wire, engine.animations(), plan().joint_count, plan().morph_target_count);
        !s.ok()) {
      return s;
    }
    // The clips' weights tracks, sampled and blended by Check: the frame's morph weights,
    // known here since the engine checks them at Submit.
    if (!pose_.morph_weights().empty()) {
      SparseMorphWeights(pose_.morph_weights(), &morph_);
      request.morph_weights = morph_;
    }
    palette_.resize(12ull * plan().joint_count);
    request.palette = palette_;
    return Status::Ok();
  }
  // The palette's bytes change hands: the job takes the request's string (parsed from the
  // wire, the one copy) and gives its last one back for the next parse to fill, so the
  // engine reads the floats where the parse put them.
  std::string& bytes = *wire.mutable_palette();
  if (bytes.size() % sizeof(float) != 0) {
    return InvalidArgument(
        fmt::format("palette holds {} bytes, not a whole number of float32 values", bytes.size()));
  }
  palette_bytes_.swap(bytes);
  request.palette = PaletteFloats(palette_bytes_, &palette_);
  return Status::Ok();
}

void FrameJob::SetOutputs() {
  const FrameLayout& l = layout_;
  request.encoded = {};
  request.positions = {};
  request.normals = {};
  request.tangents = {};
  request.device = {};
  if (gpu_region_) {  // written on the device (gpu/gpu_frame_output.cpp)
    SetGpuOutput();
  } else if (device_encoded_) {
    const std::size_t tangent_bytes = l.tangent_values * EncodedBytesPerValue(encoding_);
    request.encoded = {
        .encoding = encoding_,
        .positions = {PositionsOut(), l.payload},
        .normals =
            want_normals_ ? std::span<std::byte>(NormalsOut(), l.payload) : std::span<std::byte>(),
        .tangents = want_tangents_ ? std::span<std::byte>(TangentsOut(), tangent_bytes)
                                   : std::span<std::byte>(),
        .bounds = boxed_ ? bounds_.data() : nullptr,
        .box_scratch = box_scratch_ ? Reuse(positions_, l.values) : std::span<float>()};
  } else if (encoding_ == VertexEncoding::kFloat32) {
    // Skinned straight into the wire buffer or the region, aligned for SIMD.
    const auto floats = [](std::byte* out, uint64_t count) {
      return std::span<float>(reinterpret_cast<float*>(out), count);
    };
    request.positions = floats(PositionsOut(), l.values);
    if (want_normals_) request.normals = floats(NormalsOut(), l.values);
    if (want_tangents_) request.tangents = floats(TangentsOut(), l.tangent_values);
  } else if (!l.scratch) {
    request.positions = Reuse(positions_, l.values);
    if (want_normals_) request.normals = Reuse(normals_, l.values);
    if (want_tangents_) request.tangents = Reuse(tangents_, l.tangent_values);
  }
  request.skin_into_scratch = l.scratch;
  request.scratch_normals = l.scratch && want_normals_;
}

Status FrameJob::Begin(uint64_t frame, const std::string& backend) {
  record_.Begin(backend);
  frame_ = tick_character_ >= 0 ? tick_frame_ : frame;  // a tick's characters: the tick's
  done_ = false;
  error_part_ = false;
  part_count_ = next_part_ = 0;
  early_ = false;
  ready_instances_ = 0;
  parts_ready_.store(0, std::memory_order_relaxed);
  if (wire_in_use()) return Internal("a frame job was reused while gRPC still sent its answer");
  result_ = Status::Ok();
  timing_ = {};
  vertices_ = 0;
  instances_ = 1;
  region_.reset();
  gpu_region_.reset();
  return Status::Ok();
}

void FrameJob::Refuse(uint64_t frame, const std::string& backend, Status status) {
  if (Status s = Begin(frame, backend); !s.ok()) status = std::move(s);
  Fail(std::move(status));
}

Status FrameJob::PlaceInRegion(const v1::OutputRegion& output) {
  const uint64_t offset = output.offset();
  if (offset % wire::kRegionAlignment != 0) {
    return InvalidArgument(fmt::format("output.offset = {} in region '{}' is not a multiple of {}",
                                       offset, output.region(), wire::kRegionAlignment));
  }
  // The wire contract's rule, as the client computes it; an offset past the region is
  // refused by the range check (CheckRegionRange), naming it.
  const wire::RegionLayout at =
      wire::LayoutInRegion(offset, vertices_, instances_, encoding_, want_normals_, want_tangents_);
  region_positions_ = at.positions_offset;
  region_normals_ = at.normals_offset;
  region_tangents_ = at.tangents_offset;
  region_end_ = at.end_offset;
  return Status::Ok();
}

Status FrameJob::PinRegion(const v1::OutputRegion& output, const RegionCaller& regions,
                           RegionHandle* handle) {
  // Looked up, checked and guarded once per stream and region (RegionHandle); the range
  // is checked every frame, against the region that stands now.
  Result<std::shared_ptr<MappedRegion>> region = handle->Resolve(output.region(), regions);
  if (!region.ok()) return region.status();
  if (Status s = CheckRegionRange(output, (*region)->byte_size()); !s.ok()) return s;
  region_ = std::move(region).value();
  return Status::Ok();
}

Status FrameJob::CheckRegionRange(const v1::OutputRegion& output, uint64_t size) const {
  const uint64_t offset = output.offset();
  const uint64_t limit =
      output.byte_size() == 0 ? size : std::min(size, offset + std::min(output.byte_size(), size));
  if (offset > size || region_end_ > limit) {
    return InvalidArgument(fmt::format(
        "frame {} needs bytes [{}, {}) of region '{}' ({} instance(s) of {} vertices{}), but {}",
        frame_, offset, region_end_, output.region(), instances_, vertices_,
        want_tangents_  ? " with normals and tangents"
        : want_normals_ ? " with normals"
                        : "",
        limit < size ? fmt::format("output.byte_size = {} allows {} from the offset",
                                   output.byte_size(), output.byte_size())
                     : fmt::format("the region holds {} bytes", size)));
  }
  return Status::Ok();
}

std::byte* FrameJob::PositionsOut() {
  return region_ ? region_->bytes().data() + region_positions_ : wire_.data();
}

std::byte* FrameJob::NormalsOut() {
  return region_ ? region_->bytes().data() + region_normals_ : wire_.data() + normals_offset_;
}

std::byte* FrameJob::TangentsOut() {
  return region_ ? region_->bytes().data() + region_tangents_ : wire_.data() + tangents_offset_;
}

Status FrameJob::FillInputs() { return pose_.Evaluate(palette_); }

void FrameJob::Fail(Status status) {
  DropPlan();  // never submitted: the mesh is not pinned for it
  pose_.Release();
  region_.reset();
  gpu_region_.reset();
  result_ = std::move(status);
  record_.EndFailed(result_.code());
  SetErrorPart();
}

void FrameJob::OnSkinned(Status status, const FrameTiming& timing) {
  timing_ = timing;
  result_ = std::move(status);
  if (region_) {  // the frame is in the region: check nobody took it away meanwhile
    if (result_.ok() && region_->removed()) {
      result_ = FailedPrecondition(fmt::format(
          "region '{}' was unregistered while frame {} was in flight: its output is undefined",
          region_->name(), frame_));
    }
    // A write that met a truncated page was caught by the guard, which marked the region.
    if (result_.ok()) result_ = region_->CheckNotBroken();
    if (result_.ok()) region_->CountFrame();
  }
  if (gpu_region_ && result_.ok()) result_ = GpuRegionStillThere();
  if (result_.ok()) result_ = WriteHeaders();
  region_.reset();  // an unregister waiting for this frame may answer from here
  // A tick's character holds its GPU region until the tick has signalled it (TakeGpuRegion).
  if (tick_character_ < 0 || !result_.ok()) gpu_region_.reset();
  if (result_.ok()) {
    record_.EndAnswered(timing_, encode_ns_.load());
  } else {
    record_.EndFailed(result_.code());
    SetErrorPart();
  }
  listener_->OnFrameDone(this);  // may reuse this job at once: nothing after
}

Status FrameJob::OnInstanceSkinned(uint32_t instance, std::span<const float> positions,
                                   std::span<const float> normals) {
  // float32 is skinned in place, and a backend that encodes writes the bytes itself.
  if (encoding_ != VertexEncoding::kFloat32 && !device_encoded_) {
    const auto started = std::chrono::steady_clock::now();
    Status s = EncodeInstance(instance, positions, normals);
    encode_ns_.fetch_add(std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::steady_clock::now() - started)
                             .count());
    if (!s.ok()) return s;
  }
  return early_ ? MarkInstanceReady(instance) : Status::Ok();
}

Status FrameJob::EncodeInstance(uint32_t i, std::span<const float> positions,
                                std::span<const float> normals) {
  const std::size_t instance_bytes = positions.size() * EncodedBytesPerValue(encoding_);
  Bounds& bounds = bounds_[i];
  bounds = {};
  if (boxed_) {
    Result<Bounds> box = ComputeBounds(positions);
    if (!box.ok()) return InstanceError(box.status(), i, instances_);
    bounds = *box;
  }
  Status s = EncodePositions(encoding_, positions, bounds,
                             {PositionsOut() + i * instance_bytes, instance_bytes});
  if (s.ok() && want_normals_) {
    s = EncodeNormals(encoding_, normals, {NormalsOut() + i * instance_bytes, instance_bytes});
  }
  if (s.ok() && want_tangents_) {  // never in scratch: the instance's part of tangents_
    const std::size_t count = kValuesPerTangent * vertices_;
    const std::size_t bytes = EncodedTangentBytes(encoding_, vertices_);
    s = EncodeTangents(encoding_, request.tangents.subspan(i * count, count),
                       {TangentsOut() + i * bytes, bytes});
  }
  return s.ok() ? s : InstanceError(s, i, instances_);
}

void FrameJob::SetCommonHeader(bool with_timing) {
  header_.Clear();
  header_.set_frame(frame_);
  header_.set_total_vertices(vertices_);
  header_.set_instances(instances_);
  header_.set_encoding(ToWire(encoding_));
  if (tick_character_ >= 0) header_.set_character(static_cast<uint32_t>(tick_character_));
  if (!with_timing) return;
  v1::ServerTiming* timing = header_.mutable_timing();
  timing->set_queued_ns(timing_.queued_ns);
  timing->set_compute_ns(timing_.compute_ns);
  timing->set_device_transfer_ns(timing_.device_transfer_ns);
  timing->set_device_kernel_ns(timing_.device_kernel_ns);
  timing->set_encode_ns(encode_ns_.load());
}

Status FrameJob::WriteHeaders() {
  SetCommonHeader(/*with_timing=*/true);
  if (region_ || gpu_region_) {
    Status s = WriteRegionHeader();
    if (s.ok()) parts_ready_.store(1, std::memory_order_release);
    return s;
  }
  // Early parts already went out with their headers: only the rest are written now.
  std::lock_guard lock(parts_mutex_);
  for (std::size_t p = parts_ready_.load(std::memory_order_relaxed); p < part_count_; ++p) {
    if (Status s = WritePartHeader(p); !s.ok()) return s;
  }
  parts_ready_.store(part_count_, std::memory_order_release);
  return Status::Ok();
}

Status FrameJob::WritePartHeader(std::size_t p) {
  const PartRange r = RangeOf(p);
  header_.set_first_vertex(r.first);
  header_.set_vertex_count(r.count);
  header_.set_instance(r.instance);
  header_.set_last(p + 1 == part_count_ && tick_character_ < 0);  // a tick ends in its own part
  if (instances_per_part_ > 1) header_.set_instance_count(r.instances);
  if (boxed_) {
    ToWire(bounds_[r.instance], header_.mutable_bounds());
    header_.clear_instance_bounds();  // keeps the elements: no allocation next time
    for (uint32_t k = 0; instances_per_part_ > 1 && k < r.instances; ++k) {
      ToWire(bounds_[r.instance + k], header_.add_instance_bounds());
    }
  }
  const std::size_t payload = EncodedBytes(encoding_, r.count) * r.instances;
  std::byte* room = wire_.data() + headers_offset_ + p * header_room_;
  const std::size_t tangent_payload =
      want_tangents_ ? EncodedTangentBytes(encoding_, r.count) * r.instances : 0;
  auto framing = wire::WritePartFraming(header_, header_.ByteSizeLong(), payload, want_normals_,
                                        {room, header_room_}, tangent_payload);
  if (!framing.ok()) return framing.status();
  headers_[p] = {framing->header_bytes, framing->normals_tag_bytes, framing->tangents_tag_bytes};
  return Status::Ok();
}

Status FrameJob::MarkInstanceReady(uint32_t instance) {
  std::size_t covered = 0;
  {
    std::lock_guard lock(parts_mutex_);
    if (error_part_) return Status::Ok();
    instance_ready_[instance] = 1;
    while (ready_instances_ < instances_ && instance_ready_[ready_instances_]) ++ready_instances_;
    covered = instances_per_part_ > 1 ? ready_instances_ / instances_per_part_
                                      : ready_instances_ * parts_per_instance_;
    covered = std::min(covered, part_count_ - 1);  // the final part waits for the timings
    const std::size_t ready = parts_ready_.load(std::memory_order_relaxed);
    if (covered <= ready) return Status::Ok();
    SetCommonHeader(/*with_timing=*/false);
    for (std::size_t p = ready; p < covered; ++p) {
      if (Status s = WritePartHeader(p); !s.ok()) return s;
    }
    parts_ready_.store(covered, std::memory_order_release);
  }
  listener_->OnPartsReady(this);
  return Status::Ok();
}
Status FrameJob::WriteRegionHeader() {
  header_.set_first_vertex(0);
  header_.set_vertex_count(vertices_);
  header_.set_instance(0);
  header_.set_instance_count(instances_);
  header_.set_last(true);
  header_.clear_instance_bounds();  // keeps the elements: no allocation next time
  if (boxed_) {
    ToWire(bounds_[0], header_.mutable_bounds());
    for (uint32_t k = 0; k < instances_; ++k) ToWire(bounds_[k], header_.add_instance_bounds());
  }
  v1::RegionWrite* write = header_.mutable_region_write();
  write->set_region(region_ ? region_->name() : gpu_region_->name());
  write->set_positions_offset(region_positions_);
  write->set_normals_offset(region_normals_);
  write->set_instance_bytes(EncodedBytes(encoding_, vertices_));
  write->set_end_offset(region_end_);
  if (want_tangents_) {
    write->set_tangents_offset(region_tangents_);
    write->set_tangent_instance_bytes(EncodedTangentBytes(encoding_, vertices_));
  } else {
    write->clear_tangents_offset();
    write->clear_tangent_instance_bytes();
  }
  const std::size_t size = header_.ByteSizeLong();
  if (size > header_room_) {
    return Internal(
        fmt::format("a response header of {} bytes exceeds the {} reserved", size, header_room_));
  }
  header_.SerializeWithCachedSizesToArray(reinterpret_cast<uint8_t*>(wire_.data()));
  headers_[0] = {size, 0};
  return Status::Ok();
}

void FrameJob::SetErrorPart() {
  header_.Clear();
  header_.set_frame(frame_);
  header_.set_total_vertices(vertices_);
  header_.set_instances(instances_);
  header_.mutable_error()->set_code(ToGrpc(result_).error_code());
  header_.mutable_error()->set_message(result_.message());
  header_.set_last(true);
  grpc::ByteBuffer bytes;
  bool own = false;
  if (!grpc::SerializationTraits<v1::SkinResponse>::Serialize(header_, &bytes, &own).ok()) {
    header_.mutable_error()->set_message("the error message could not be serialized");
    (void)grpc::SerializationTraits<v1::SkinResponse>::Serialize(header_, &bytes, &own);
  }
  std::lock_guard lock(parts_mutex_);
  // With early parts out, gRPC may be writing the last one handed out: it stays.
  if (next_part_ == 0) out_.reset();
  error_part_ = true;
  error_bytes_ = std::move(bytes);
  part_count_ = next_part_ + 1;  // after the early parts already handed out, if any
}

bool FrameJob::HasPartToSend() {
  std::lock_guard lock(parts_mutex_);
  if (error_part_) return next_part_ < part_count_;
  return next_part_ < parts_ready_.load(std::memory_order_acquire);
}

const grpc::ByteBuffer* FrameJob::NextPart(bool* last) {
  std::lock_guard lock(parts_mutex_);
  if (error_part_) {
    if (next_part_ >= part_count_) return nullptr;
    next_part_ = part_count_;
    *last = true;
    // Early parts went out over the wire buffer: the error part ends them.
    wire_slice_ = grpc::Slice();
    return &error_bytes_;
  }
  if (next_part_ >= parts_ready_.load(std::memory_order_acquire)) return nullptr;
  const std::size_t p = next_part_++;
  *last = next_part_ == part_count_;
  if (p == 0) {  // gRPC gets slices of wire_: hold the listener until it lets go of them
    wire_refs_.store(1, std::memory_order_release);
    listener_->HoldForWire();
    wire_slice_ = grpc::Slice(wire_.data(), wire_used_, &FrameJob::WireReleased, this);
  }
  if (region_part_) {  // one part, header only: the vertices are in the region
    const grpc::Slice slice = wire_slice_.sub(0, headers_[0].size);
    out_.emplace(&slice, 1);
    wire_slice_ = grpc::Slice();
    return &*out_;
  }
  const PartRange r = RangeOf(p);
  const std::size_t bytes_per_vertex = EncodedBytes(encoding_, 1);
  const std::size_t payload = std::size_t{r.count} * r.instances * bytes_per_vertex;
  const std::size_t offset =
      (static_cast<std::size_t>(r.instance) * vertices_ + r.first) * bytes_per_vertex;
  const std::size_t header = headers_offset_ + p * header_room_;
  const PartHeader& h = headers_[p];
  grpc::Slice slices[6] = {wire_slice_.sub(header, header + h.size),
                           wire_slice_.sub(offset, offset + payload)};
  std::size_t n = 2;
  if (want_normals_) {
    slices[n++] = wire_slice_.sub(header + h.size, header + h.size + h.normals_tag_size);
    slices[n++] = wire_slice_.sub(normals_offset_ + offset, normals_offset_ + offset + payload);
  }
  if (want_tangents_) {  // 4 values a vertex where the others have 3
    const std::size_t tag = header + h.size + h.normals_tag_size;
    const std::size_t at = tangents_offset_ + offset / kValuesPerVertex * kValuesPerTangent;
    slices[n++] = wire_slice_.sub(tag, tag + h.tangents_tag_size);
    slices[n++] = wire_slice_.sub(at, at + payload / kValuesPerVertex * kValuesPerTangent);
  }
  out_.emplace(slices, n);
  if (*last) wire_slice_ = grpc::Slice();  // the parts' slices hold the buffer from here on
  return &*out_;
}

void FrameJob::DropWire() {
  out_.reset();
  wire_slice_ = grpc::Slice();
}

void FrameJob::WireReleased(void* job) {
  auto* self = static_cast<FrameJob*>(job);
  Listener* listener = self->listener_;
  self->wire_refs_.store(0, std::memory_order_release);  // the job may be reused from here
  listener->ReleaseForWire();
}

}  // namespace skinserve::server
