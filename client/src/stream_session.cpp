#include "stream_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "skinserve/client/idle_watchdog.h"

namespace skinserve::client {

// One stream of the session. Members in this order: the watchdog goes before the stream,
// the stream before its context.
struct StreamSession::Attempt {
  explicit Attempt(SkinClient& client)
      : stream(client.StreamSkinRaw(&context)), watchdog(&context, client.limits().stream_idle) {}

  grpc::ClientContext context;
  std::unique_ptr<SkinClient::RawStream> stream;
  IdleWatchdog watchdog;
  bool broken = false;  // a unit's answer never came whole
  // A failed Write means the server has ended the stream (e.g. it is shutting down); the
  // answers it sent before are still to be read, and gRPC's Finish only returns once they
  // are, so stop writing but keep reading.
  bool writes_closed = false;
  uint64_t heard = 0;  // answers this stream brought, good or not
};

StreamSession::StreamSession(SkinClient& client, const SessionOptions& options, StreamPath& path)
    : client_(client),
      options_(options),
      path_(path),
      window_(static_cast<std::size_t>(std::max(options.window, 1))),
      end_(options.first + options.count),
      next_(options.first),
      in_flight_(window_) {}

bool StreamSession::MoreNew() const {
  return next_ < end_ && !(options_.stop != nullptr && options_.stop->load());
}

Status StreamSession::Run() {
  Status status;
  while (MoreNew() || !resend_.empty()) {
    bool go_on = false;
    status = RunStream(&go_on);
    if (!go_on) break;
  }
  return status;
}

Status StreamSession::RunStream(bool* go_on) {
  Attempt attempt(client_);
  // A unit that cannot be made ends the session: the stream is cancelled, not finished.
  const auto abandon = [&](Status why) {
    attempt.context.TryCancel();
    (void)attempt.stream->Finish();
    *go_on = false;
    return why;
  };
  if (Status s = Fill(attempt); !s.ok()) return abandon(s);
  while (!in_flight_.empty()) {
    if (!ReadAnswer(attempt)) {
      attempt.broken = true;
      break;
    }
    ++attempt.heard;
    SettleHead();
    if (Status s = Fill(attempt); !s.ok()) return abandon(s);
  }
  return Retry(attempt, go_on);
}

// Sends units until the window is full, resends first.
Status StreamSession::Fill(Attempt& attempt) {
  while (!attempt.broken && !attempt.writes_closed && in_flight_.size() < window_ &&
         (!resend_.empty() || MoreNew())) {
    const bool again = !resend_.empty();
    const uint64_t frame = again ? resend_.front() : next_;
    const std::size_t slot = in_flight_.next_slot();
    if (Status s = path_.Prepare(frame, slot); !s.ok()) return s;
    in_flight_.push_back({frame, SessionClock::now(), reuploads_, slot});
    if (again) {
      resend_.pop_front();
    } else {
      ++next_;
      ++counts_.sent;
    }
    if (!attempt.stream->Write(path_.request())) attempt.writes_closed = true;
  }
  attempt.watchdog.Awaiting(!in_flight_.empty());
  return Status::Ok();
}

// Reads the oldest unit's answer; false when the stream ended before it was whole.
bool StreamSession::ReadAnswer(Attempt& attempt) {
  path_.BeginAnswer(in_flight_.front());
  while (attempt.stream->Read(&bytes_)) {
    attempt.watchdog.Answered();
    if (path_.AddPart(bytes_)) return true;
  }
  return false;
}

void StreamSession::SettleHead() {
  const InFlight head = in_flight_.front();  // a copy: the slot is reused
  in_flight_.pop_front();
  switch (path_.Settle(head, *this)) {
    case StreamPath::Settled::kResend:
      resend_.push_back(head.frame);
      break;
    case StreamPath::Settled::kAnswered:
      ++counts_.answered;
      break;
    case StreamPath::Settled::kFailed:
      ++counts_.failed;
      break;
  }
}

// The stream ended: finishes it and decides whether a new one carries on.
Status StreamSession::Retry(Attempt& attempt, bool* go_on) {
  if (!attempt.writes_closed) attempt.stream->WritesDone();
  Status status = wire::FromGrpc(attempt.stream->Finish());
  if (attempt.watchdog.fired()) {
    status = DeadlineExceeded(
        fmt::format("no answer for {:.1f} s with {} {}(s) in flight: the stream's idle limit "
                    "(CallLimits::stream_idle; --stream-idle-seconds)",
                    attempt.watchdog.limit().count() / 1000.0, in_flight_.size(), options_.unit));
  }
  // Everything so far answered on a stream that ended cleanly: more to send?
  *go_on = !attempt.broken && !attempt.writes_closed && status.ok();
  if (*go_on) return status;
  if (status.ok())
    status = Internal(fmt::format("the stream ended with {}s unanswered", options_.unit));
  // A stream that got answers before it broke (e.g. one a server ended at its maximum
  // connection age, or a replica that went away) starts the count anew: max_reconnects
  // bounds reconnects in a row that bring no answer.
  if (counts_.answered > answered_at_reconnect_) reconnects_in_a_row_ = 0;
  // UNAVAILABLE: the connection or the replica went; an idle stream: its server stopped
  // answering. Either way the next stream may find a live replica (round_robin).
  const bool reconnect = (status.code() == StatusCode::kUnavailable || attempt.watchdog.fired()) &&
                         reconnects_in_a_row_ < options_.max_reconnects;
  if (reconnect && attempt.heard == 0) {
    // UNAVAILABLE before the stream's first answer: it never got going (typically gRPC's
    // "GOAWAY received", a stream opened on a connection the server was just ageing out).
    // A unit is a pure function of its inputs, so its units go on the next stream.
    std::vector<uint64_t> again;
    in_flight_.ForEach([&](const InFlight& f) { again.push_back(f.frame); });
    resend_.insert(resend_.begin(), again.begin(), again.end());
  } else {
    // The stream broke after answering: its unanswered units are failed, never silently
    // dropped (the server may be gone mid-unit; the caller decides what to do).
    in_flight_.ForEach([&](const InFlight& f) {
      ++counts_.failed;
      path_.Fail(f, status);
    });
  }
  in_flight_.clear();
  *go_on = reconnect;
  if (reconnect) {
    ++reconnects_in_a_row_;
    ++counts_.reconnects;
    answered_at_reconnect_ = counts_.answered;
  }
  return status;
}

}  // namespace skinserve::client
