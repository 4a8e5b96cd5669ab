#include "skinserve/client/frame_stream.h"

#include <fmt/format.h>

#include <algorithm>
#include <optional>

#include "skinserve/client/lost_upload.h"
#include "stream_session.h"

namespace skinserve::client {
namespace {

// Frames in flight each need their own bytes of the region.
Status CheckRegionSlots(const StreamOptions& options, std::size_t window) {
  if (!options.output.enabled()) return Status::Ok();
  if (window > 1 && options.output.stride == 0) {
    return InvalidArgument(
        "StreamOptions.output.stride is 0 with a window above 1: frames in flight would share "
        "the region's bytes (use wire::RegionFrameBytes)");
  }
  if (options.output.offset + window * options.output.stride > options.output.region->byte_size()) {
    return InvalidArgument(fmt::format(
        "region '{}' holds {} bytes, fewer than {} frames in flight of {} bytes from offset {}",
        options.output.name, options.output.region->byte_size(), window, options.output.stride,
        options.output.offset));
  }
  return Status::Ok();
}

// A frame's request, answer and re-upload for the session.
class FramePath final : public StreamPath {
 public:
  FramePath(const StreamOptions& options, const PaletteSource& palette, const FrameSink& sink)
      : options_(options), palette_(palette), sink_(sink) {
    // One request, one response part and one result for the whole run: protobuf keeps the
    // strings' capacity and the result its vectors', so steady frames allocate nothing here.
    request_.set_mesh_id(options.mesh_id);
    request_.set_backend(options.backend);
    request_.set_want_normals(options.want_normals);
    request_.set_want_tangents(options.want_tangents);
    request_.set_encoding(static_cast<v1::Encoding>(options.encoding));
    request_.set_instances(options.instances);
    request_.set_pack_instances(true);  // FrameAssembler takes packed parts
    request_.set_method(wire::ToWire(options.method));
    request_.set_early_parts(options.early_parts);
    if (options.output.enabled()) request_.mutable_output()->set_region(options.output.name);
  }

  Status Prepare(uint64_t frame, std::size_t slot) override {
    request_.set_frame(frame);
    // A pose replaces the palette (the server refuses both set); the field not sent is
    // cleared, its capacity kept for the next frame that sends it.
    const Pose pose = options_.pose ? options_.pose(frame) : Pose{};
    if (pose.empty()) {
      request_.clear_pose();
      wire::EncodeFloats(palette_(frame), request_.mutable_palette());
    } else {
      request_.mutable_palette()->clear();
      PoseToWire(pose, &request_);
    }
    if (options_.morph_weights) wire::MorphWeightsToWire(options_.morph_weights(frame), &request_);
    if (options_.instance_morph_weights) {
      wire::InstanceMorphWeightsToWire(options_.instance_morph_weights(frame), &request_);
    }
    if (options_.output.enabled()) {
      request_.mutable_output()->set_offset(options_.output.offset + slot * options_.output.stride);
    }
    return Status::Ok();
  }
  const v1::SkinRequest& request() const override { return request_; }

  void BeginAnswer(const InFlight&) override { assembler_.emplace(&options_.output); }
  bool AddPart(const grpc::ByteBuffer& part) override {
    return assembler_->Add(part, &part_, &result_);
  }

  Settled Settle(const InFlight& head, StreamSession& session) override {
    if (result_.frame != head.frame) {
      result_.status = Internal(fmt::format("frame {} answered where frame {} was due ({})",
                                            result_.frame, head.frame, result_.status.ToString()));
    }
    // NOT_FOUND: the server lost the mesh, or the skeleton or a clip the frame's pose names
    // (evicted, deleted, or a replica that never had it).
    if (result_.status.code() == StatusCode::kNotFound) {
      if (session.SentBeforeReupload(head)) return Settled::kResend;
      if (session.MayReupload()) {
        const Status reupload =
            session.client().Reupload(LostUploadOf(result_.status, options_.mesh_id));
        // Sent (or, UNAVAILABLE, lost on its way: a connection the server was ageing out, a
        // replica going away; round_robin's next pick may be the stream's replica): either
        // way one attempt of max_reuploads, and the frame goes again.
        if (WorthResending(reupload)) {
          session.CountReuploadAttempt();
          if (reupload.ok()) session.CountReuploaded();
          return Settled::kResend;
        }
        // The frame's NOT_FOUND, and why what it lacks could not go again.
        result_.status = Status(result_.status.code(),
                                fmt::format("{}; re-uploading it failed: {}",
                                            result_.status.message(), reupload.ToString()));
      }
    }
    const Settled settled = result_.status.ok() ? Settled::kAnswered : Settled::kFailed;
    sink_(result_, SessionClock::now() - head.sent);
    return settled;
  }

  void Fail(const InFlight& f, const Status& why) override {
    FrameResult failed;
    failed.frame = f.frame;
    failed.status = why;
    sink_(failed, SessionClock::now() - f.sent);
  }

 private:
  const StreamOptions& options_;
  const PaletteSource& palette_;
  const FrameSink& sink_;
  v1::SkinRequest request_;
  RawPart part_;  // reads each answer part from gRPC's bytes (no copy into a message)
  std::optional<FrameAssembler> assembler_;
  FrameResult result_;
};

}  // namespace

Status StreamFrames(SkinClient& client, const StreamOptions& options, const PaletteSource& palette,
                    const FrameSink& sink, StreamSummary* summary_out) {
  const std::size_t window = static_cast<std::size_t>(std::max(options.window, 1));
  if (Status s = CheckRegionSlots(options, window); !s.ok()) return s;
  FramePath path(options, palette, sink);
  StreamSession session(
      client, SessionOptionsOf(options, options.first_frame, options.frames, "frame"), path);
  const Status status = session.Run();
  if (summary_out != nullptr) CopyCounts(session.counts(), summary_out);
  return status;
}

}  // namespace skinserve::client
