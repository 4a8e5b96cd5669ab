// FrameJob's part for frames into GPU regions (SkinRequest.output with gpu set,
// docs/serving/gpu-regions.md): the region resolved for the caller, the layout of
// shared-memory regions (the stream plan's) in any encoding the backend writes itself,
// checked against its size, and the engine's DeviceOutput.
#include "frames/frame_job.h"

namespace skinserve::server {

Status FrameJob::PinGpuRegion(const v1::OutputRegion& output, const RegionCaller& regions) {
  if (regions.gpu_regions == nullptr) {
    return FailedPrecondition(
        "output names a GPU region (output.gpu), but this server's GPU regions are off "
        "(--gpu-fd-socket is empty)");
  }
  if (!regions.owner.ok()) return regions.owner.status();
  Result<std::shared_ptr<GpuRegion>> region =
      regions.gpu_regions->Acquire(output.region(), *regions.owner);
  if (!region.ok()) return region.status();
  if (Status s = CheckRegionRange(output, (*region)->byte_size()); !s.ok()) return s;
  gpu_region_ = std::move(region).value();
  return Status::Ok();
}

void FrameJob::SetGpuOutput() {
  request.device = {.memory = &gpu_region_->memory(),
                    .positions_offset = region_positions_,
                    .normals_offset = region_normals_,
                    .tangents_offset = region_tangents_,
                    .instance_bytes = EncodedBytes(encoding_, vertices_),
                    .tangent_instance_bytes = EncodedTangentBytes(encoding_, vertices_),
                    .normals = want_normals_,
                    .tangents = want_tangents_,
                    .encoding = encoding_,
                    .bounds = boxed_ ? bounds_.data() : nullptr};
}

// Also where a GPU region's semaphore is signalled: once per frame, after all its
// instances are in the buffer, before the answer (GpuRegion::FrameWritten). A tick's
// characters do not: the tick signals each of its regions once (TickJob::SignalGpuRegions),
// since a binary semaphore signalled twice before its wait is invalid.
Status FrameJob::GpuRegionStillThere() {
  return tick_character_ < 0 ? gpu_region_->FrameWritten(frame_) : gpu_region_->StillThere(frame_);
}

}  // namespace skinserve::server
