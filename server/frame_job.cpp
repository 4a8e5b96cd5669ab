#include "frame_job.h"

#include <algorithm>

#include "wire_codec.h"

namespace skinserve::server {

Status FrameJob::Prepare(const v1::SkinRequest& request, const Engine& engine,
                         const std::string& default_backend, SkinRequest* engine_request) {
  frame_ = request.frame();
  auto mesh = engine.GetMesh(request.mesh_id());
  if (!mesh.ok()) return mesh.status();
  vertex_count_ = mesh->vertex_count;
  want_normals_ = request.want_normals();
  if (want_normals_ && !mesh->has_normals) {
    return InvalidArgument("want_normals is set but mesh " + mesh->id + " has no normals");
  }
  engine_request->mesh_id = request.mesh_id();
  engine_request->backend = request.backend().empty() ? default_backend : request.backend();
  auto method = FromWire(request.method());
  if (!method.ok()) return method.status();
  engine_request->method = *method;
  if (Status s = DecodeFloats(request.palette(), "palette", &engine_request->palette); !s.ok()) {
    return s;
  }
  positions_.resize(3ull * vertex_count_);
  normals_.resize(want_normals_ ? 3ull * vertex_count_ : 0);
  engine_request->positions = positions_;
  engine_request->normals = normals_;
  return Status::Ok();
}

void FrameJob::Complete(Status status, FrameTiming timing) {
  status_ = std::move(status);
  timing_ = timing;
  done_ = true;
}

bool FrameJob::NextPart(v1::SkinResponse* part) {
  if (finished_) return false;
  const auto started = std::chrono::steady_clock::now();
  part->Clear();
  part->set_frame(frame_);
  part->set_total_vertices(vertex_count_);
  if (!status_.ok()) {
    part->mutable_error()->set_code(ToGrpc(status_).error_code());
    part->mutable_error()->set_message(status_.message());
    part->set_last(true);
    finished_ = true;
    return true;
  }
  const std::size_t bytes_per_vertex = (want_normals_ ? 2 : 1) * 3 * sizeof(float);
  const uint32_t per_part =
      static_cast<uint32_t>(std::max<std::size_t>(1, kMaxPartPayloadBytes / bytes_per_vertex));
  const uint32_t count = std::min(per_part, vertex_count_ - next_vertex_);
  part->set_first_vertex(next_vertex_);
  part->set_vertex_count(count);
  const std::size_t offset = 3ull * next_vertex_, length = 3ull * count * sizeof(float);
  part->set_positions(reinterpret_cast<const char*>(positions_.data() + offset), length);
  if (want_normals_) {
    part->set_normals(reinterpret_cast<const char*>(normals_.data() + offset), length);
  }
  next_vertex_ += count;
  finished_ = next_vertex_ >= vertex_count_;
  part->set_last(finished_);
  encode_ns_ += std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now() - started)
                    .count();
  v1::ServerTiming* timing = part->mutable_timing();
  timing->set_queued_ns(timing_.queued_ns);
  timing->set_compute_ns(timing_.compute_ns);
  timing->set_encode_ns(encode_ns_);  // so far; complete on the last part
  return true;
}

}  // namespace skinserve::server
