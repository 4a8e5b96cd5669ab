// FrameJob's tick mode (TickJob): the character's index in its parts and its header in the
// tick's final part. Kept apart from frame_job.cpp: plain frames never run this.
#include <fmt/format.h>

#include "frames/frame_job.h"
#include "rpc/server_messages.h"

namespace skinserve::server {

void FrameJob::SetTickCharacter(uint32_t character, uint64_t frame) {
  tick_character_ = character;
  tick_frame_ = frame;
}

void FrameJob::TickHeader(v1::SkinResponse* out) const {
  out->Clear();  // keeps its sub-messages' storage for the next tick
  out->set_frame(tick_frame_);
  out->set_character(static_cast<uint32_t>(std::max<int64_t>(tick_character_, 0)));
  out->set_total_vertices(vertices_);
  out->set_instances(instances_);
  out->set_last(true);
  if (!result_.ok()) {
    out->mutable_error()->set_code(ToGrpc(result_).error_code());
    out->mutable_error()->set_message(
        fmt::format("character {}: {}", tick_character_, result_.message()));
    return;
  }
  out->set_encoding(ToWire(encoding_));
  v1::ServerTiming* timing = out->mutable_timing();
  timing->set_queued_ns(timing_.queued_ns);
  timing->set_compute_ns(timing_.compute_ns);
  timing->set_device_transfer_ns(timing_.device_transfer_ns);
  timing->set_device_kernel_ns(timing_.device_kernel_ns);
  timing->set_encode_ns(encode_ns_.load());
  if (!region_part_) return;  // its vertices went out in its parts
  // header_ still holds the region part WriteRegionHeader wrote.
  out->set_vertex_count(vertices_);
  out->set_instance_count(instances_);
  *out->mutable_region_write() = header_.region_write();
  if (header_.has_bounds()) *out->mutable_bounds() = header_.bounds();
  out->mutable_instance_bounds()->CopyFrom(header_.instance_bounds());
}

}  // namespace skinserve::server
