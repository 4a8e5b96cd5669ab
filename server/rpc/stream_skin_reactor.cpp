#include "rpc/stream_skin_reactor.h"

#include <fmt/format.h>
#include <grpcpp/impl/codegen/proto_utils.h>

#include "rpc/server_messages.h"

namespace skinserve::server {

StreamSkinReactor::StreamSkinReactor(Engine* engine, std::string default_backend, int window,
                                     OpenStreams* open_streams, InflightBudget* budget,
                                     RegionCaller regions, const SkinRequestLimits& limits)
    : engine_(engine),
      default_backend_(std::move(default_backend)),
      window_(static_cast<std::size_t>(std::max(window, 1))),
      open_streams_(open_streams),
      budget_(budget),
      regions_(std::move(regions)),
      reader_(budget, WithMaxInstances(limits, engine)),
      ticks_(static_cast<FrameJob::Listener*>(this), budget) {
  jobs_.reserve(window_);
  in_flight_jobs_.resize(window_, nullptr);
  idle_jobs_.reserve(window_);
  const Status accepted = open_streams_->Add(this);
  std::lock_guard lock(mutex_);
  if (engine_ == nullptr) {
    FinishLocked(ToGrpc(Unavailable("the server is starting: backends are being built")));
  } else if (!accepted.ok()) {
    FinishLocked(ToGrpc(accepted));
  } else {
    PumpLocked();
  }
}

void StreamSkinReactor::OnReadDone(bool ok) {
  FrameJob* job = PrepareRead(ok);
  if (job == nullptr) return;
  // Outside the lock: a small frame is skinned right here (Engine::Run) and its answer
  // started from OnFrameDone on this thread, with no compute thread woken and no thread
  // woken to write it.
  Status status = engine_->Run(job);
  if (status.ok()) return;
  refs_.fetch_sub(1);  // refused: the engine will not call back
  std::lock_guard lock(mutex_);
  job->Fail(std::move(status));  // answered with its error
  job->set_done();
  PumpLocked();
}

FrameJob* StreamSkinReactor::PrepareRead(bool ok) {
  std::lock_guard lock(mutex_);
  reading_ = false;
  if (finished_) return nullptr;  // ended meanwhile (drained or cancelled): nobody awaits
  if (!ok) {
    reads_done_ = true;  // the client half-closed (or went away)
    PumpLocked();
    return nullptr;
  }
  ++requests_read_;
  Status read = reader_.Read(&request_bytes_);
  if (!read.ok() && reader_.scan().malformed) {
    // Not a SkinRequest at all: nothing names the frame, so the stream cannot go on.
    FinishLocked(ToGrpc(InvalidArgument(fmt::format(
        "message {} on this stream is not a valid skinserve.v1.SkinRequest", requests_read_))));
    return nullptr;
  }
  const uint64_t frame = read.ok() ? reader_.request().frame() : reader_.scan().frame;
  last_frame_read_ = frame;
  if (read.ok() && reader_.request().characters_size() > 0) {  // a tick: tick_job.h
    StartTickLocked();
    return nullptr;
  }
  FrameJob& job = *TakeIdleJobLocked();
  in_flight_jobs_[(oldest_ + in_flight_) % window_] = &job;
  ++in_flight_;
  if (!read.ok()) {  // a limit: this frame fails, the stream goes on
    job.Refuse(frame, default_backend_, std::move(read));
    job.set_done();
    PumpLocked();
    return nullptr;
  }
  Status status =
      job.Prepare(*reader_.mutable_request(), *engine_, default_backend_, regions_, &plan_);
  reader_.Trim();      // the job took what it keeps
  if (!status.ok()) {  // answered with its error
    job.Fail(std::move(status));
    job.set_done();
  }
  // The next read is started before the frame is skinned: it overlaps the skinning.
  PumpLocked();
  if (!status.ok()) return nullptr;
  refs_.fetch_add(1);  // the engine's, until OnFrameDone
  return &job;
}

void StreamSkinReactor::StartTickLocked() {
  TickJob& tick = ticks_.Take();
  in_flight_jobs_[(oldest_ + in_flight_) % window_] = &tick;
  ++in_flight_;
  refs_.fetch_add(1);
  if (!tick.Start(*reader_.mutable_request(), *engine_, default_backend_, regions_)) {
    refs_.fetch_sub(1);  // answered already: no callback comes
    tick.set_done();
  }
  reader_.Trim();  // the characters' jobs took what they keep
  PumpLocked();
}

void StreamSkinReactor::OnFrameDone(StreamAnswer* job) {
  {
    std::lock_guard lock(mutex_);
    job->set_done();
    if (oldest_written_ && job == &Slot(oldest_)) RetireOldestLocked();
    PumpLocked();
  }
  Unref();
}

void StreamSkinReactor::OnPartsReady(StreamAnswer*) {
  std::lock_guard lock(mutex_);
  PumpLocked();  // the oldest frame may have a part to write now
}

void StreamSkinReactor::OnWriteDone(bool ok) {
  std::lock_guard lock(mutex_);
  writing_ = false;
  Slot(oldest_).PartWritten();
  if (writing_last_part_) {  // the oldest frame is answered: its job is free once done
    writing_last_part_ = false;
    if (Slot(oldest_).done()) {
      RetireOldestLocked();
    } else {
      oldest_written_ = true;  // OnFrameDone retires it
    }
  }
  if (!ok) {  // the client is gone: nothing more can be delivered
    FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
    return;
  }
  PumpLocked();
}

void StreamSkinReactor::RetireOldestLocked() {
  oldest_written_ = false;
  if (!ticks_.Recycle(&Slot(oldest_))) idle_jobs_.push_back(static_cast<FrameJob*>(&Slot(oldest_)));
  oldest_ = (oldest_ + 1) % window_;
  if (--in_flight_ == 0) {
    quiet_since_.store(std::chrono::steady_clock::now().time_since_epoch().count());
  }
}

void StreamSkinReactor::OnCancel() {
  std::lock_guard lock(mutex_);
  FinishLocked(grpc::Status::CANCELLED);
}

void StreamSkinReactor::OnDone() {
  open_streams_->Remove(this);
  {
    std::lock_guard lock(mutex_);
    for (auto& job : jobs_) job->DropWire();  // a frame cut off mid-way holds its buffer
    ticks_.DropWire();
  }
  Unref();
}

void StreamSkinReactor::Drain() {
  std::lock_guard lock(mutex_);
  draining_ = true;
  PumpLocked();
}

bool StreamSkinReactor::EndIfQuietSince(std::chrono::steady_clock::time_point cutoff,
                                        const std::string& why) {
  std::lock_guard lock(mutex_);
  if (finished_ || draining_ || in_flight_ > 0 || writing_ || quiet_since() > cutoff) return false;
  // Every frame read was answered: the client may open a new stream and carry on.
  FinishLocked(ToGrpc(Unavailable(
      last_frame_read_
          ? fmt::format("{}; every frame read on it was answered (the last read was "
                        "frame {}): send later frames on a new stream",
                        why, *last_frame_read_)
          : fmt::format("{}; no frame was read on it: send frames on a new stream", why))));
  return true;
}

FrameJob* StreamSkinReactor::TakeIdleJobLocked() {
  // The job answered last whose buffer gRPC has let go of; else a new one.
  for (auto it = idle_jobs_.rbegin(); it != idle_jobs_.rend(); ++it) {
    if (!(*it)->wire_in_use()) {
      FrameJob* job = *it;
      idle_jobs_.erase(std::next(it).base());
      return job;
    }
  }
  jobs_.push_back(std::make_unique<FrameJob>(static_cast<FrameJob::Listener*>(this), budget_));
  return jobs_.back().get();
}

void StreamSkinReactor::PumpLocked() {
  if (finished_) return;
  // Write the oldest frame's next part once it is done: responses keep request order.
  if (!writing_ && in_flight_ > 0 && Slot(oldest_).HasPartToSend()) {
    bool last = false;
    if (const grpc::ByteBuffer* part = Slot(oldest_).NextPart(&last)) {
      writing_ = true;
      writing_last_part_ = last;
      StartWrite(part);
    }
  }
  if (!reading_ && !reads_done_ && !draining_ && in_flight_ < window_) {
    reading_ = true;
    StartRead(&request_bytes_);
  }
  if (in_flight_ > 0 || writing_) return;
  if (reads_done_) {
    FinishLocked(grpc::Status::OK);
  } else if (draining_) {
    // Every frame read has been answered; the client resends the rest elsewhere.
    FinishLocked(ToGrpc(Unavailable(
        last_frame_read_
            ? fmt::format("the server is shutting down: every frame read on this stream was "
                          "answered (the last read was frame {}); send later frames to another "
                          "replica",
                          *last_frame_read_)
            : std::string("the server is shutting down; no frame was read on this stream; "
                          "send them to another replica"))));
  }
}

void StreamSkinReactor::FinishLocked(const grpc::Status& status) {
  if (finished_) return;
  finished_ = true;
  Finish(status);
}

void StreamSkinReactor::Unref() {
  if (refs_.fetch_sub(1) == 1) delete this;
}

}  // namespace skinserve::server
