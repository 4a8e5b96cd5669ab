// StreamTicks: StreamFrames' loop for ticks. Each tick in flight keeps its own Tick (the
// window's slot), whose characters' outputs its answer is checked against.
#include <fmt/format.h>

#include <deque>
#include <set>
#include <vector>

#include "skinserve/client/idle_watchdog.h"
#include "skinserve/client/tick.h"

namespace skinserve::client {
namespace {

using Clock = std::chrono::steady_clock;

struct TickInFlight {
  uint64_t frame = 0;
  Clock::time_point sent;
  int uploads_before = 0;  // re-uploads done when it was sent
  std::size_t slot = 0;
};

bool HasRegionCharacter(const Tick& tick) {
  for (const TickCharacter& c : tick.characters()) {
    if (c.options.output.enabled()) return true;
  }
  return false;
}

// The characters of `result` answered NOT_FOUND: their meshes.
std::set<std::string> LostMeshes(const Tick& tick, const TickResult& result) {
  std::set<std::string> lost;
  for (std::size_t i = 0; i < tick.size() && i < result.characters.size(); ++i) {
    if (result.characters[i].status.code() == StatusCode::kNotFound) {
      lost.insert(tick.character(i).mesh_id);
    }
  }
  return lost;
}

}  // namespace

Status StreamTicks(SkinClient& client, const TickStreamOptions& options, const TickSource& source,
                   const TickSink& sink, TickStreamSummary* summary_out) {
  TickStreamSummary summary;
  const uint64_t end = options.first_tick + options.ticks;
  uint64_t next = options.first_tick;
  std::deque<uint64_t> resend;  // ticks to send again after a re-upload
  const std::size_t window = static_cast<std::size_t>(std::max(options.window, 1));
  std::vector<Tick> ticks(window);  // each slot's tick, kept for its answer
  std::deque<TickInFlight> in_flight;
  std::vector<std::size_t> free_slots;
  for (std::size_t s = window; s-- > 0;) free_slots.push_back(s);
  int reuploads = 0;
  Status status;
  v1::SkinRequest request;  // reused: its characters' messages keep their storage
  RawPart part;
  grpc::ByteBuffer bytes;
  TickResult result;

  const auto count = [&](const TickResult& r) {
    const std::size_t failed = r.failed();
    summary.characters_failed += failed;
    summary.characters_answered += r.characters.size() - failed;
  };
  const auto report_failed = [&](const TickInFlight& f, const Status& why) {
    TickResult failed;
    failed.frame = f.frame;
    failed.status = why;
    failed.characters.resize(ticks[f.slot].size());
    for (FrameResult& r : failed.characters) r.frame = f.frame, r.status = why;
    ++summary.failed;
    count(failed);
    sink(failed, Clock::now() - f.sent);
  };

  int reconnects_in_a_row = 0;
  uint64_t answered_at_reconnect = 0;
  auto more_new = [&] { return next < end && !(options.stop != nullptr && options.stop->load()); };
  while (more_new() || !resend.empty()) {
    grpc::ClientContext context;
    auto stream = client.StreamSkinRaw(&context);
    IdleWatchdog watchdog(&context, client.limits().stream_idle);
    bool broken = false, writes_closed = false;
    uint64_t heard = 0;
    auto fill = [&]() -> Status {
      while (!broken && !writes_closed && in_flight.size() < window &&
             (!resend.empty() || more_new())) {
        const bool again = !resend.empty();
        const uint64_t frame = again ? resend.front() : next;
        const std::size_t slot = free_slots.back();
        Tick& tick = ticks[slot];
        tick.Clear();
        tick.set_frame(frame);
        source(frame, &tick);
        if (HasRegionCharacter(tick) && window > 1 && options.region_stride == 0) {
          return InvalidArgument(
              "TickStreamOptions.region_stride is 0 with a window above 1: ticks in flight would "
              "share the region's bytes");
        }
        free_slots.pop_back();
        tick.ToWire(&request, slot * options.region_stride);
        in_flight.push_back({frame, Clock::now(), reuploads, slot});
        if (again) {
          resend.pop_front();
        } else {
          ++next;
          ++summary.sent;
        }
        if (!stream->Write(request)) writes_closed = true;
      }
      watchdog.Awaiting(!in_flight.empty());
      return Status::Ok();
    };
    const auto abandon = [&](Status s) {
      context.TryCancel();
      (void)stream->Finish();
      return s;
    };
    if (Status s = fill(); !s.ok()) return abandon(s);
    while (!broken && !in_flight.empty()) {
      const TickInFlight head = in_flight.front();
      bool complete = false;
      {
        TickAssembler assembler(ticks[head.slot], &result);
        while (!complete && stream->Read(&bytes)) {
          watchdog.Answered();
          complete = assembler.Add(bytes, &part);
        }
      }
      if (!complete) {
        broken = true;
        break;
      }
      in_flight.pop_front();
      ++heard;
      // Characters whose mesh the server lost: a tick sent before the last re-upload just
      // goes again; else their meshes go again first, at most max_reuploads times.
      const std::set<std::string> lost =
          result.status.ok() ? LostMeshes(ticks[head.slot], result) : std::set<std::string>();
      bool again = !lost.empty() && head.uploads_before < reuploads;
      if (!lost.empty() && !again && reuploads < options.max_reuploads) {
        ++reuploads;
        again = true;
        for (const std::string& mesh_id : lost) {
          const Status s = client.Reupload(mesh_id);
          summary.reuploads += s.ok() ? 1 : 0;
          if (!s.ok() && s.code() != StatusCode::kUnavailable) again = false;
        }
      }
      if (again) {
        resend.push_back(head.frame);
      } else {
        if (result.status.ok()) {
          ++summary.answered;
        } else {
          ++summary.failed;
        }
        count(result);
        sink(result, Clock::now() - head.sent);
      }
      free_slots.push_back(head.slot);
      if (Status s = fill(); !s.ok()) return abandon(s);
    }
    if (!writes_closed) stream->WritesDone();
    status = wire::FromGrpc(stream->Finish());
    if (watchdog.fired()) {
      status = DeadlineExceeded(
          fmt::format("no answer for {:.1f} s with {} tick(s) in flight: the stream's idle limit "
                      "(CallLimits::stream_idle; --stream-idle-seconds)",
                      watchdog.limit().count() / 1000.0, in_flight.size()));
    }
    if (!broken && !writes_closed && status.ok()) continue;
    if (status.ok()) status = Internal("the stream ended with ticks unanswered");
    if (summary.answered > answered_at_reconnect) reconnects_in_a_row = 0;
    const bool reconnect = (status.code() == StatusCode::kUnavailable || watchdog.fired()) &&
                           reconnects_in_a_row < options.max_reconnects;
    if (reconnect && heard == 0) {  // it never got going: its ticks go on the next stream
      for (auto it = in_flight.rbegin(); it != in_flight.rend(); ++it) resend.push_front(it->frame);
    } else {
      for (const TickInFlight& f : in_flight) report_failed(f, status);
    }
    for (const TickInFlight& f : in_flight) free_slots.push_back(f.slot);
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
