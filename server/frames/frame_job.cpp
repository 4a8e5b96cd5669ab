#include "frames/frame_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include <grpcpp/impl/codegen/proto_utils.h>

#include "rpc/engine_messages.h"
#include "skinserve/wire/part_framing.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::server {
namespace {

// Room for one part's header: the fields besides the vertex data take at most ~160
// bytes (varints, the timings, a snorm16 box), and the two tags with their lengths 12;
// a packed part adds each instance's box (32 bytes with its tag and length).
constexpr std::size_t kHeaderRoom = 256;
constexpr std::size_t kBoundsRoom = 40;

constexpr std::size_t RoundUp(std::size_t n) {
  return (n + kBufferAlignment - 1) / kBufferAlignment * kBufferAlignment;
}

// Grows `buffer` to hold `count` values (never shrinks, so alternating sizes do not
// re-zero it) and returns the first `count`.
std::span<float> Reuse(std::vector<float>& buffer, std::size_t count) {
  if (buffer.size() < count) buffer.resize(count);
  return {buffer.data(), count};
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

Status FrameJob::Prepare(const v1::SkinRequest& wire, Engine& engine,
                         const std::string& default_backend, const RegionCaller& regions,
                         RegionHandle* region) {
  if (Status s = Begin(wire.frame(), wire.backend().empty() ? default_backend : wire.backend());
      !s.ok()) {
    return s;
  }
  // The engine checks the backend, the method, the mesh and the batch once, and pins the
  // mesh: its shape sizes the buffers below, and Submit looks nothing up again.
  request.mesh_id.assign(wire.mesh_id());
  request.backend.assign(wire.backend().empty() ? default_backend : wire.backend());
  Result<SkinningMethod> method = FromWire(wire.method());
  if (!method.ok()) return method.status();
  request.method = *method;
  request.instances = std::max<uint32_t>(wire.instances(), 1);
  if (Status s = MorphWeightsFromWire(wire, &morph_); !s.ok()) return s;
  request.morph_weights = morph_;  // checked against the mesh by Engine::Submit
  if (Status s = InstanceMorphWeightsFromWire(wire, &instance_morph_, &instance_morph_views_);
      !s.ok()) {
    return s;
  }
  request.instance_morph_weights = instance_morph_views_;
  if (Status s = engine.Plan(this); !s.ok()) return s;
  vertices_ = plan().vertex_count;
  want_normals_ = wire.want_normals();
  if (want_normals_ && !plan().has_normals) {
    return InvalidArgument("want_normals is set but mesh " + wire.mesh_id() + " has no normals");
  }
  want_tangents_ = wire.want_tangents();
  if (want_tangents_) {
    if (!want_normals_) {
      return InvalidArgument("want_tangents is set without want_normals; ask for normals too");
    }
    if (!plan().has_tangents) {
      return InvalidArgument("want_tangents is set but mesh " + wire.mesh_id() +
                             " has no tangents (MeshHeader.has_tangents)");
    }
    if (!plan().backend_tangents) {
      return FailedPrecondition(fmt::format(
          "want_tangents is set but backend '{}' does not skin tangents (BackendInfo.tangents); "
          "ask without tangents or choose a backend whose BackendInfo.tangents is set",
          request.backend));
    }
  }
  Result<VertexEncoding> encoding = FromWire(wire.encoding());
  if (!encoding.ok()) return encoding.status();
  encoding_ = *encoding;
  boxed_ = QuantisedToBox(encoding_);
  instances_ = request.instances;

  const uint64_t values = 3ull * vertices_ * instances_;
  const uint64_t arrays = want_normals_ ? 2 : 1;
  const uint64_t tangent_values = want_tangents_ ? kValuesPerTangent * vertices_ * instances_ : 0;
  const bool float32 = encoding_ == VertexEncoding::kFloat32;
  const std::size_t vertex_bytes =
      (arrays * 3 + (want_tangents_ ? kValuesPerTangent : 0)) * EncodedBytesPerValue(encoding_);
  vertices_per_part_ =
      static_cast<uint32_t>(std::max<std::size_t>(1, kMaxPartPayloadBytes / vertex_bytes));
  parts_per_instance_ =
      std::max<std::size_t>(1, (vertices_ + vertices_per_part_ - 1) / vertices_per_part_);
  part_count_ = parts_per_instance_ * instances_;
  // Packed: as many whole instances per part as fit in 1 MiB.
  instances_per_part_ = 1;
  if (wire.pack_instances() && parts_per_instance_ == 1 && vertices_ > 0) {
    instances_per_part_ = static_cast<uint32_t>(
        std::min<std::size_t>(instances_, kMaxPartPayloadBytes / (vertex_bytes * vertices_)));
    instances_per_part_ = std::max<uint32_t>(instances_per_part_, 1);
    part_count_ = (instances_ + instances_per_part_ - 1) / instances_per_part_;
  }
  header_room_ =
      kHeaderRoom + (boxed_ && instances_per_part_ > 1 ? kBoundsRoom * instances_per_part_ : 0);
  const std::size_t payload = values * EncodedBytesPerValue(encoding_);
  normals_offset_ = RoundUp(payload);  // the positions start the buffer
  tangents_offset_ = normals_offset_ + (want_normals_ ? RoundUp(payload) : 0);
  headers_offset_ = tangents_offset_ + RoundUp(static_cast<std::size_t>(tangent_values) *
                                               EncodedBytesPerValue(encoding_));
  region_part_ = wire.has_output();
  if (region_part_) {  // the vertices go into the region: the wire carries one header
    if (Status s = wire.output().gpu() ? PrepareGpuRegion(wire.output(), regions)
                                       : PrepareRegion(wire.output(), regions, region);
        !s.ok()) {
      return s;
    }
    part_count_ = 1;
    instances_per_part_ = 1;
    header_room_ =
        kHeaderRoom + wire.output().region().size() + (boxed_ ? kBoundsRoom * instances_ : 0);
    normals_offset_ = tangents_offset_ = headers_offset_ = 0;
  }
  wire_used_ = headers_offset_ + part_count_ * header_room_;
  early_ = wire.early_parts() && !region_part_ && part_count_ > 1 && instances_ > 1;
  if (early_) instance_ready_.assign(instances_, 0);  // keeps its capacity

  // Encoded instance by instance: skinned into the compute thread's scratch, kept in its
  // core's cache, unless an instance is too large for it.
  // Tangents are never skinned into scratch (the engine's rule): such frames keep floats.
  // A backend that writes this encoding itself (on its device: only the encoded bytes come
  // back) skins straight into the wire buffer or the region, and sends the boxes it found.
  device_encoded_ = !float32 && plan().BackendWrites(encoding_);
  // snorm16 written by a host backend (simd): it keeps the positions as floats until it has
  // their box, in this job's buffer, so that they are counted below.
  box_scratch_ = device_encoded_ && boxed_ && plan().backend_box_scratch;
  const bool scratch =
      !float32 && !device_encoded_ && !want_tangents_ &&
      ScratchFloatsPerInstance(vertices_, want_normals_) <= kMaxScratchFloatsPerInstance;
  // What this frame holds while in flight; the job keeps its buffers, so only growth is
  // charged.
  uint64_t floats_kept = 0;
  if (box_scratch_) {
    floats_kept = values * sizeof(float);
  } else if (!float32 && !scratch && !device_encoded_) {
    floats_kept = (arrays * values + tangent_values) * sizeof(float);
  }
  const uint64_t need = wire.palette().size() + floats_kept + std::max(wire_used_, wire_.size());
  if (need > charged_) {
    if (Status s = budget_->TryCharge(need - charged_); !s.ok()) return s;
    charged_ = need;
  }

  if (Status s = DecodeFloats(wire.palette(), "palette", &palette_); !s.ok()) return s;
  request.palette = palette_;
  encode_ns_.store(0);
  if (headers_.size() < part_count_) headers_.resize(part_count_);
  if (bounds_.size() < instances_) bounds_.resize(instances_);

  if (wire_.size() < wire_used_) wire_ = AlignedBuffer<std::byte>(wire_used_);
  request.encoded = {};
  request.device = {};
  if (gpu_region_) {  // written on the device (gpu/gpu_frame_output.cpp)
    SetGpuOutput();
  } else if (device_encoded_) {
    request.positions = {};
    request.normals = {};
    request.tangents = {};
    const std::size_t tangent_bytes = tangent_values * EncodedBytesPerValue(encoding_);
    request.encoded = {
        .encoding = encoding_,
        .positions = {PositionsOut(), payload},
        .normals =
            want_normals_ ? std::span<std::byte>(NormalsOut(), payload) : std::span<std::byte>(),
        .tangents = want_tangents_ ? std::span<std::byte>(TangentsOut(), tangent_bytes)
                                   : std::span<std::byte>(),
        .bounds = boxed_ ? bounds_.data() : nullptr,
        .box_scratch = box_scratch_ ? Reuse(positions_, values) : std::span<float>()};
  } else if (float32) {  // skinned straight into the wire buffer or the region, aligned for SIMD
    const auto floats = [&](std::byte* out) {
      return std::span<float>(reinterpret_cast<float*>(out), values);
    };
    request.positions = floats(PositionsOut());
    request.normals = want_normals_ ? floats(NormalsOut()) : std::span<float>();
    request.tangents =
        want_tangents_ ? std::span<float>(reinterpret_cast<float*>(TangentsOut()), tangent_values)
                       : std::span<float>();
  } else if (scratch) {
    request.positions = {};
    request.normals = {};
    request.tangents = {};
  } else {
    request.positions = Reuse(positions_, values);
    request.normals = want_normals_ ? Reuse(normals_, values) : std::span<float>();
    request.tangents = want_tangents_ ? Reuse(tangents_, tangent_values) : std::span<float>();
  }
  request.skin_into_scratch = scratch;
  request.scratch_normals = scratch && want_normals_;
  return Status::Ok();
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

Status FrameJob::PrepareRegion(const v1::OutputRegion& output, const RegionCaller& regions,
                               RegionHandle* handle) {
  // Looked up, checked and guarded once per stream and region (RegionHandle).
  Result<std::shared_ptr<MappedRegion>> region = handle->Resolve(output.region(), regions);
  if (!region.ok()) return region.status();
  if (Status s = LayOutInRegion(output, (*region)->byte_size()); !s.ok()) return s;
  region_ = std::move(region).value();
  return Status::Ok();
}

Status FrameJob::LayOutInRegion(const v1::OutputRegion& output, uint64_t size) {
  const uint64_t offset = output.offset();
  if (offset % wire::kRegionAlignment != 0) {
    return InvalidArgument(fmt::format("output.offset = {} in region '{}' is not a multiple of {}",
                                       offset, output.region(), wire::kRegionAlignment));
  }
  const wire::RegionLayout layout =
      wire::LayoutInRegion(offset, vertices_, instances_, encoding_, want_normals_, want_tangents_);
  region_positions_ = layout.positions_offset;
  region_normals_ = layout.normals_offset;
  region_tangents_ = layout.tangents_offset;
  region_end_ = layout.end_offset;
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

void FrameJob::Fail(Status status) {
  DropPlan();  // never submitted: the mesh is not pinned for it
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
  gpu_region_.reset();
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
