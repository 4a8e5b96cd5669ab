#include "skinserve/client/frame_stream.h"

#include <fmt/format.h>

#include <deque>
#include <vector>

#include "skinserve/client/channel.h"
#include "skinserve/client/idle_watchdog.h"

namespace skinserve::client {
namespace {

// Whether a re-upload's outcome leaves the frame worth sending again: it went through, or
// it was lost on its way (UNAVAILABLE) and the next attempt may find the stream's replica.
bool Retried(const Status& reupload) {
  return reupload.ok() || reupload.code() == StatusCode::kUnavailable;
}

using Clock = std::chrono::steady_clock;

struct InFlight {
  uint64_t frame;
  Clock::time_point sent;
  int uploads_before;  // re-uploads done when it was sent
};

// The frames in flight, oldest first: a ring of `window` slots allocated once (a deque
// would allocate and free a block every few dozen frames).
class InFlightRing {
 public:
  explicit InFlightRing(std::size_t window) : slots_(window) {}
  bool empty() const { return size_ == 0; }
  std::size_t size() const { return size_; }
  // Returns the slot it took: frames in flight never share one (a region's slots follow it).
  std::size_t push_back(const InFlight& f) {
    const std::size_t slot = (head_ + size_++) % slots_.size();
    slots_[slot] = f;
    return slot;
  }
  const InFlight& front() const { return slots_[head_]; }
  void pop_front() {
    head_ = (head_ + 1) % slots_.size();
    --size_;
  }
  template <typename F>
  void ForEach(F f) const {
    for (std::size_t i = 0; i < size_; ++i) f(slots_[(head_ + i) % slots_.size()]);
  }
  void clear() { head_ = size_ = 0; }

 private:
  std::vector<InFlight> slots_;
  std::size_t head_ = 0, size_ = 0;
};

}  // namespace

Status StreamFrames(SkinClient& client, const StreamOptions& options, const PaletteSource& palette,
                    const FrameSink& sink, StreamSummary* summary_out) {
  StreamSummary summary;
  const uint64_t end = options.first_frame + options.frames;
  uint64_t next = options.first_frame;
  std::deque<uint64_t> resend;  // frames to send again after a re-upload
  const std::size_t window = static_cast<std::size_t>(std::max(options.window, 1));
  InFlightRing in_flight(window);
  int reuploads = 0;
  if (options.output.enabled() && window > 1 && options.output.stride == 0) {
    return InvalidArgument(
        "StreamOptions.output.stride is 0 with a window above 1: frames in flight would share "
        "the region's bytes (use wire::RegionFrameBytes)");
  }
  if (options.output.enabled() &&
      options.output.offset + window * options.output.stride > options.output.region->byte_size()) {
    return InvalidArgument(fmt::format(
        "region '{}' holds {} bytes, fewer than {} frames in flight of {} bytes from offset {}",
        options.output.name, options.output.region->byte_size(), window, options.output.stride,
        options.output.offset));
  }
  Status status;
  // One request, one response part and one result for the whole run: protobuf keeps the
  // strings' capacity and the result its vectors', so steady frames allocate nothing here.
  v1::SkinRequest request;
  request.set_mesh_id(options.mesh_id);
  request.set_backend(options.backend);
  request.set_want_normals(options.want_normals);
  request.set_want_tangents(options.want_tangents);
  request.set_encoding(static_cast<v1::Encoding>(options.encoding));
  request.set_instances(options.instances);
  request.set_pack_instances(true);  // FrameAssembler takes packed parts
  request.set_method(wire::ToWire(options.method));
  request.set_early_parts(options.early_parts);
  if (options.output.enabled()) request.mutable_output()->set_region(options.output.name);
  RawPart part;  // reads each answer part from gRPC's bytes (no copy into a message)
  grpc::ByteBuffer bytes;
  FrameResult result;

  auto report_failed = [&](uint64_t frame, const Status& why, Clock::time_point sent) {
    FrameResult failed;
    failed.frame = frame;
    failed.status = why;
    ++summary.failed;
    sink(failed, Clock::now() - sent);
  };

  int reconnects_in_a_row = 0;
  uint64_t answered_at_reconnect = 0;
  auto more_new = [&] { return next < end && !(options.stop != nullptr && options.stop->load()); };
  while (more_new() || !resend.empty()) {
    grpc::ClientContext context;
    auto stream = client.StreamSkinRaw(&context);
    IdleWatchdog watchdog(&context, client.limits().stream_idle);
    bool broken = false;
    // A failed Write means the server has ended the stream (e.g. it is shutting down); the
    // answers it sent before are still to be read, and gRPC's Finish only returns once
    // they are, so stop writing but keep reading.
    bool writes_closed = false;
    uint64_t heard = 0;  // answers this stream brought, good or not
    auto fill = [&] {
      while (!broken && !writes_closed && in_flight.size() < window &&
             (!resend.empty() || more_new())) {
        const bool again = !resend.empty();
        const uint64_t frame = again ? resend.front() : next;
        request.set_frame(frame);
        wire::EncodeFloats(palette(frame), request.mutable_palette());
        if (options.morph_weights) wire::MorphWeightsToWire(options.morph_weights(frame), &request);
        if (options.instance_morph_weights) {
          wire::InstanceMorphWeightsToWire(options.instance_morph_weights(frame), &request);
        }
        const std::size_t slot = in_flight.push_back({frame, Clock::now(), reuploads});
        if (options.output.enabled()) {
          request.mutable_output()->set_offset(options.output.offset +
                                               slot * options.output.stride);
        }
        if (again) {
          resend.pop_front();
        } else {
          ++next;
          ++summary.sent;
        }
        if (!stream->Write(request)) writes_closed = true;
      }
      watchdog.Awaiting(!in_flight.empty());
    };
    fill();
    while (!broken && !in_flight.empty()) {
      FrameAssembler assembler(&options.output);
      bool complete = false;
      while (!complete && stream->Read(&bytes)) {
        watchdog.Answered();
        complete = assembler.Add(bytes, &part, &result);
      }
      if (!complete) {
        broken = true;
        break;
      }
      const InFlight head = in_flight.front();  // a copy: the slot is reused
      in_flight.pop_front();
      ++heard;
      if (result.frame != head.frame) {
        result.status = Internal(
            fmt::format("frame {} answered where frame {} was due", result.frame, head.frame));
      }
      // NOT_FOUND: the server lost the mesh (evicted, or a replica that never had it). A
      // frame sent before the last re-upload just goes again; else the mesh goes again
      // first, at most max_reuploads times.
      const bool not_found = result.status.code() == StatusCode::kNotFound;
      const bool sent_before_reupload = not_found && head.uploads_before < reuploads;
      const bool may_reupload =
          not_found && !sent_before_reupload && reuploads < options.max_reuploads;
      const Status reupload = may_reupload ? client.Reupload(options.mesh_id) : Status::Ok();
      if (sent_before_reupload) {
        resend.push_back(head.frame);
      } else if (may_reupload && Retried(reupload)) {
        // Sent (or, UNAVAILABLE, lost on its way: a connection the server was ageing out, a
        // replica going away; round_robin's next pick may be the stream's replica): either
        // way one attempt of max_reuploads, and the frame goes again.
        ++reuploads;
        summary.reuploads += reupload.ok() ? 1 : 0;
        resend.push_back(head.frame);
      } else if (!result.status.ok()) {
        if (!reupload.ok()) {  // the frame's NOT_FOUND, and why the mesh could not go again
          result.status = Status(result.status.code(),
                                 fmt::format("{}; re-uploading it failed: {}",
                                             result.status.message(), reupload.ToString()));
        }
        ++summary.failed;
        sink(result, Clock::now() - head.sent);
      } else {
        ++summary.answered;
        sink(result, Clock::now() - head.sent);
      }
      fill();
    }
    if (!writes_closed) stream->WritesDone();
    status = wire::FromGrpc(stream->Finish());
    if (watchdog.fired()) {
      status = DeadlineExceeded(
          fmt::format("no answer for {:.1f} s with {} frame(s) in flight: the stream's idle limit "
                      "(CallLimits::stream_idle; --stream-idle-seconds)",
                      watchdog.limit().count() / 1000.0, in_flight.size()));
    }
    // Everything so far answered on a stream that ended cleanly: more to send?
    if (!broken && !writes_closed && status.ok()) continue;
    if (status.ok()) status = Internal("the stream ended with frames unanswered");
    // A stream that got answers before it broke (e.g. one a server ended at its maximum
    // connection age, or a replica that went away) starts the count anew: max_reconnects
    // bounds reconnects in a row that bring no answer.
    if (summary.answered > answered_at_reconnect) reconnects_in_a_row = 0;
    // UNAVAILABLE: the connection or the replica went; an idle stream: its server stopped
    // answering. Either way the next stream may find a live replica (round_robin).
    const bool reconnect = (status.code() == StatusCode::kUnavailable || watchdog.fired()) &&
                           reconnects_in_a_row < options.max_reconnects;
    if (reconnect && heard == 0) {
      // UNAVAILABLE before the stream's first answer: it never got going (typically gRPC's
      // "GOAWAY received", a stream opened on a connection the server was just ageing out).
      // A frame is a pure function of mesh and palette, so its frames go on the next stream.
      std::vector<uint64_t> again;
      in_flight.ForEach([&](const InFlight& f) { again.push_back(f.frame); });
      resend.insert(resend.begin(), again.begin(), again.end());
    } else {
      // The stream broke after answering: its unanswered frames are failed, never silently
      // dropped (the server may be gone mid-frame; the caller decides what to do).
      in_flight.ForEach([&](const InFlight& f) { report_failed(f.frame, status, f.sent); });
    }
    in_flight.clear();
    if (!reconnect) break;
    ++reconnects_in_a_row;
    ++summary.reconnects;
    answered_at_reconnect = summary.answered;
  }
  if (summary_out != nullptr) *summary_out = summary;
  return status;
}

}  // namespace skinserve::client
