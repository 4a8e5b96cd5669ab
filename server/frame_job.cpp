#include "frame_job.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>

#include "wire_codec.h"

namespace skinserve::server {
namespace {

std::span<std::byte> WritableBytes(std::string* bytes, std::size_t size) {
  bytes->resize(size);  // grows once; later frames of the same size reuse the capacity
  return {reinterpret_cast<std::byte*>(bytes->data()), size};
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

FrameJob::~FrameJob() { budget_->Release(charged_); }

Status FrameJob::Prepare(const v1::SkinRequest& wire, const Engine& engine,
                         const std::string& default_backend) {
  record_.Begin(wire.backend().empty() ? default_backend : wire.backend());
  frame_ = wire.frame();
  done_ = false;
  result_ = Status::Ok();
  timing_ = {};
  part_count_ = next_part_ = 0;
  mesh_.vertex_count = 0;
  instances_ = 1;
  if (Status s = engine.GetMesh(wire.mesh_id(), &mesh_); !s.ok()) return s;
  want_normals_ = wire.want_normals();
  if (want_normals_ && !mesh_.has_normals) {
    return InvalidArgument("want_normals is set but mesh " + mesh_.id + " has no normals");
  }
  switch (wire.encoding()) {
    case v1::ENCODING_FLOAT32:
    case v1::ENCODING_FLOAT16:
    case v1::ENCODING_SNORM16:
      encoding_ = static_cast<VertexEncoding>(wire.encoding());
      break;
    default:
      return InvalidArgument(
          fmt::format("encoding = {} is unknown; use ENCODING_FLOAT32 (0), ENCODING_FLOAT16 (1) or "
                      "ENCODING_SNORM16 (2)",
                      static_cast<int>(wire.encoding())));
  }
  if (Status s = engine.CheckBatch(mesh_.vertex_count, wire.instances()); !s.ok()) return s;
  instances_ = std::max<uint32_t>(wire.instances(), 1);

  // What this frame holds while in flight; the job keeps its buffers, so only growth is
  // charged.
  const uint64_t values = 3ull * mesh_.vertex_count * instances_;
  const uint64_t arrays = want_normals_ ? 2 : 1;
  const uint64_t need = wire.palette().size() + arrays * values * sizeof(float) +
                        arrays * values * EncodedBytesPerValue(encoding_);
  if (need > charged_) {
    if (Status s = budget_->TryCharge(need - charged_); !s.ok()) return s;
    charged_ = need;
  }

  if (Status s = DecodeFloats(wire.palette(), "palette", &palette_); !s.ok()) return s;
  request.mesh_id.assign(wire.mesh_id());
  request.backend.assign(wire.backend().empty() ? default_backend : wire.backend());
  request.palette = palette_;
  request.instances = instances_;
  Result<SkinningMethod> method = FromWire(wire.method());
  if (!method.ok()) return method.status();
  request.method = *method;
  const std::size_t vertex_bytes = arrays * 3 * EncodedBytesPerValue(encoding_);
  vertices_per_part_ =
      static_cast<uint32_t>(std::max<std::size_t>(1, kMaxPartPayloadBytes / vertex_bytes));
  parts_per_instance_ =
      std::max<std::size_t>(1, (mesh_.vertex_count + vertices_per_part_ - 1) / vertices_per_part_);
  part_count_ = parts_per_instance_ * instances_;
  encode_ns_.store(0);
  if (parts_.size() < part_count_) parts_.resize(part_count_);

  in_place_ = encoding_ == VertexEncoding::kFloat32 && part_count_ == 1;
  if (in_place_) {  // malloc'd string bytes are aligned for floats (and SSE)
    const auto floats = [&](std::string* bytes) {
      return std::span<float>(reinterpret_cast<float*>(WritableBytes(bytes, values * 4).data()),
                              values);
    };
    request.positions = floats(parts_[0].mutable_positions());
    if (want_normals_) {
      request.normals = floats(parts_[0].mutable_normals());
    } else {
      parts_[0].clear_normals();
      request.normals = {};
    }
  } else {
    request.positions = Reuse(positions_, values);
    request.normals = want_normals_ ? Reuse(normals_, values) : std::span<float>();
  }
  return Status::Ok();
}

void FrameJob::Fail(Status status) {
  result_ = std::move(status);
  record_.EndFailed(result_.code());
  SetErrorPart();
}

void FrameJob::OnSkinned(Status status, const FrameTiming& timing) {
  timing_ = timing;
  result_ = std::move(status);
  if (result_.ok()) {
    FinishParts();
    record_.EndAnswered(timing_, parts_[0].timing().encode_ns());
  } else {
    record_.EndFailed(result_.code());
    SetErrorPart();
  }
  listener_->OnFrameDone(this);  // may reuse this job at once: nothing after
}

Status FrameJob::OnInstanceSkinned(uint32_t instance) {
  if (in_place_) return Status::Ok();  // skinned straight into its part
  const auto started = std::chrono::steady_clock::now();
  Status s = EncodeInstance(instance);
  encode_ns_.fetch_add(std::chrono::duration_cast<std::chrono::nanoseconds>(
                           std::chrono::steady_clock::now() - started)
                           .count());
  return s;
}

Status FrameJob::EncodeInstance(uint32_t i) {
  const uint32_t vertex_count = mesh_.vertex_count;
  const std::size_t instance_values = 3ull * vertex_count;
  const std::span<const float> positions =
      request.positions.subspan(i * instance_values, instance_values);
  const std::span<const float> normals =
      want_normals_ ? request.normals.subspan(i * instance_values, instance_values)
                    : std::span<const float>();
  Bounds bounds;
  if (encoding_ == VertexEncoding::kSnorm16) {
    Result<Bounds> box = ComputeBounds(positions);
    if (!box.ok()) return InstanceError(box.status(), i, instances_);
    bounds = *box;
  }
  std::size_t n = i * parts_per_instance_;  // this instance's parts only: no other thread's
  uint32_t first = 0;
  do {
    const uint32_t count = std::min(vertices_per_part_, vertex_count - first);
    v1::SkinResponse& part = parts_[n++];
    part.Clear();
    part.set_frame(frame_);
    part.set_first_vertex(first);
    part.set_vertex_count(count);
    part.set_total_vertices(vertex_count);
    part.set_instance(i);
    part.set_instances(instances_);
    part.set_encoding(static_cast<v1::Encoding>(encoding_));
    if (encoding_ == VertexEncoding::kSnorm16) {
      v1::Bounds* wire = part.mutable_bounds();
      wire->set_min_x(bounds.min[0]);
      wire->set_min_y(bounds.min[1]);
      wire->set_min_z(bounds.min[2]);
      wire->set_max_x(bounds.max[0]);
      wire->set_max_y(bounds.max[1]);
      wire->set_max_z(bounds.max[2]);
    }
    const std::size_t bytes = EncodedBytes(encoding_, count);
    Status s = EncodePositions(encoding_, positions.subspan(3ull * first, 3ull * count), bounds,
                               WritableBytes(part.mutable_positions(), bytes), first);
    if (s.ok() && want_normals_) {
      s = EncodeNormals(encoding_, normals.subspan(3ull * first, 3ull * count),
                        WritableBytes(part.mutable_normals(), bytes), first);
    }
    if (!s.ok()) return InstanceError(s, i, instances_);
    first += count;
  } while (first < vertex_count);
  return Status::Ok();
}

void FrameJob::FinishParts() {
  const auto started = std::chrono::steady_clock::now();
  if (in_place_) {  // the vertices are in place already: set the rest only
    v1::SkinResponse& part = parts_[0];
    part.clear_error();
    part.clear_bounds();
    part.set_frame(frame_);
    part.set_first_vertex(0);
    part.set_vertex_count(mesh_.vertex_count);
    part.set_total_vertices(mesh_.vertex_count);
    part.set_instance(0);
    part.set_instances(1);
    part.set_encoding(v1::ENCODING_FLOAT32);
  }
  parts_[part_count_ - 1].set_last(true);
  const int64_t encode_ns =
      encode_ns_.load() + std::chrono::duration_cast<std::chrono::nanoseconds>(
                              std::chrono::steady_clock::now() - started)
                              .count();
  for (std::size_t p = 0; p < part_count_; ++p) {
    v1::ServerTiming* timing = parts_[p].mutable_timing();
    timing->set_queued_ns(timing_.queued_ns);
    timing->set_compute_ns(timing_.compute_ns);
    timing->set_device_transfer_ns(timing_.device_transfer_ns);
    timing->set_device_kernel_ns(timing_.device_kernel_ns);
    timing->set_encode_ns(encode_ns);
  }
}

void FrameJob::SetErrorPart() {
  if (parts_.empty()) parts_.resize(1);
  v1::SkinResponse& part = parts_[0];
  part.Clear();
  part.set_frame(frame_);
  part.set_total_vertices(mesh_.vertex_count);
  part.set_instances(instances_);
  part.mutable_error()->set_code(ToGrpc(result_).error_code());
  part.mutable_error()->set_message(result_.message());
  part.set_last(true);
  part_count_ = 1;
  next_part_ = 0;
}

const v1::SkinResponse* FrameJob::NextPart(bool* last) {
  if (next_part_ >= part_count_) return nullptr;
  const v1::SkinResponse* part = &parts_[next_part_++];
  *last = next_part_ == part_count_;
  return part;
}

}  // namespace skinserve::server
