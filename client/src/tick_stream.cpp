// StreamTicks: the stream session (stream_session.h) for ticks. Each tick in flight keeps
// its own Tick (the window's slot), whose characters' outputs its answer is checked against.
#include <fmt/format.h>

#include <optional>
#include <set>
#include <vector>

#include "skinserve/client/lost_upload.h"
#include "skinserve/client/tick.h"
#include "stream_session.h"

namespace skinserve::client {
namespace {

bool HasRegionCharacter(const Tick& tick) {
  for (const TickCharacter& c : tick.characters()) {
    if (c.options.output.enabled()) return true;
  }
  return false;
}

// The characters of `result` answered NOT_FOUND: what each lacks (its mesh, or its pose's
// skeleton or clip).
std::set<LostUpload> LostUploads(const Tick& tick, const TickResult& result) {
  std::set<LostUpload> lost;
  for (std::size_t i = 0; i < tick.size() && i < result.characters.size(); ++i) {
    const Status& status = result.characters[i].status;
    if (status.code() == StatusCode::kNotFound) {
      lost.insert(LostUploadOf(status, tick.character(i).mesh_id));
    }
  }
  return lost;
}

// A tick's request, answer and re-upload for the session.
class TickPath final : public StreamPath {
 public:
  TickPath(const TickStreamOptions& options, const TickSource& source, const TickSink& sink,
           TickStreamSummary* summary)
      : options_(options),
        source_(source),
        sink_(sink),
        summary_(summary),
        ticks_(static_cast<std::size_t>(std::max(options.window, 1))) {}

  Status Prepare(uint64_t frame, std::size_t slot) override {
    Tick& tick = ticks_[slot];
    tick.Clear();
    tick.set_frame(frame);
    source_(frame, &tick);
    if (HasRegionCharacter(tick) && ticks_.size() > 1 && options_.region_stride == 0) {
      return InvalidArgument(
          "TickStreamOptions.region_stride is 0 with a window above 1: ticks in flight would "
          "share the region's bytes");
    }
    tick.ToWire(&request_, slot * options_.region_stride);
    return Status::Ok();
  }
  const v1::SkinRequest& request() const override { return request_; }

  void BeginAnswer(const InFlight& head) override {
    assembler_.emplace(ticks_[head.slot], &result_);
  }
  bool AddPart(const grpc::ByteBuffer& part) override { return assembler_->Add(part, &part_); }

  Settled Settle(const InFlight& head, StreamSession& session) override {
    assembler_.reset();
    // Characters whose mesh (or pose's skeleton or clip) the server lost: those go again
    // first (the session's re-upload rule), then the tick.
    const std::set<LostUpload> lost =
        result_.status.ok() ? LostUploads(ticks_[head.slot], result_) : std::set<LostUpload>();
    if (!lost.empty()) {
      if (session.SentBeforeReupload(head)) return Settled::kResend;
      if (session.MayReupload() && Reupload(lost, session)) return Settled::kResend;
    }
    Count(result_);
    sink_(result_, SessionClock::now() - head.sent);
    return result_.status.ok() ? Settled::kAnswered : Settled::kFailed;
  }

  void Fail(const InFlight& f, const Status& why) override {
    TickResult failed;
    failed.frame = f.frame;
    failed.status = why;
    failed.characters.resize(ticks_[f.slot].size());
    for (FrameResult& r : failed.characters) r.frame = f.frame, r.status = why;
    Count(failed);
    sink_(failed, SessionClock::now() - f.sent);
  }

 private:
  // One attempt of max_reuploads for all of `lost`; whether the tick is worth sending again.
  static bool Reupload(const std::set<LostUpload>& lost, StreamSession& session) {
    session.CountReuploadAttempt();
    bool again = true;
    for (const LostUpload& upload : lost) {
      const Status s = session.client().Reupload(upload);
      if (s.ok()) session.CountReuploaded();
      if (!WorthResending(s)) again = false;
    }
    return again;
  }

  void Count(const TickResult& r) {
    const std::size_t failed = r.failed();
    summary_->characters_failed += failed;
    summary_->characters_answered += r.characters.size() - failed;
  }

  const TickStreamOptions& options_;
  const TickSource& source_;
  const TickSink& sink_;
  TickStreamSummary* summary_;  // its characters' counts
  std::vector<Tick> ticks_;     // each slot's tick, kept for its answer
  v1::SkinRequest request_;     // reused: its characters' messages keep their storage
  RawPart part_;
  std::optional<TickAssembler> assembler_;
  TickResult result_;
};

}  // namespace

Status StreamTicks(SkinClient& client, const TickStreamOptions& options, const TickSource& source,
                   const TickSink& sink, TickStreamSummary* summary_out) {
  TickStreamSummary summary;
  TickPath path(options, source, sink, &summary);
  StreamSession session(client,
                        SessionOptionsOf(options, options.first_tick, options.ticks, "tick"), path);
  const Status status = session.Run();
  CopyCounts(session.counts(), &summary);
  if (summary_out != nullptr) *summary_out = summary;
  return status;
}

}  // namespace skinserve::client
