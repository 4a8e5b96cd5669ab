#include "rpc/skin_reactor.h"

#include "frames/skin_request_reader.h"
#include "rpc/server_messages.h"

namespace skinserve::server {

SkinReactor::SkinReactor(Engine* engine, const std::string& default_backend,
                         const grpc::ByteBuffer& request_bytes, InflightBudget* budget,
                         RegionCaller regions, const SkinRequestLimits& limits)
    : job_(static_cast<FrameJob::Listener*>(this), budget) {
  grpc::ByteBuffer bytes(request_bytes);  // reading consumes it
  Status status = Unavailable("the server is starting: backends are being built");
  StreamPlan plan;  // one frame: planned (and its region resolved) for it alone
  if (engine != nullptr) {
    // Held (and charged) only until the job took what it keeps.
    SkinRequestReader reader(budget, WithMaxInstances(limits, engine));
    status = reader.Read(&bytes);
    if (status.ok() && reader.request().characters_size() > 0) {  // a tick: tick_job.h
      StartTick(*reader.mutable_request(), *engine, default_backend, regions, budget);
      return;
    }
    status = status.ok()
                 ? job_.Prepare(*reader.mutable_request(), *engine, default_backend, regions, &plan)
                 : status;
  }
  if (status.ok()) {
    refs_.fetch_add(1);
    status = engine->Run(&job_);           // a small frame is skinned here, answered from here
    if (!status.ok()) refs_.fetch_sub(1);  // refused: the engine will not call back
  }
  if (!status.ok()) {
    job_.Fail(status);  // the frame's verdict (for the metrics)
    std::lock_guard lock(mutex_);
    FinishLocked(ToGrpc(status));
  }
}

void SkinReactor::StartTick(v1::SkinRequest& request, Engine& engine,
                            const std::string& default_backend, const RegionCaller& regions,
                            InflightBudget* budget) {
  tick_ = std::make_unique<TickJob>(static_cast<FrameJob::Listener*>(this), budget);
  answer_ = tick_.get();
  refs_.fetch_add(1);
  if (tick_->Start(request, engine, default_backend, regions)) return;
  refs_.fetch_sub(1);  // answered already: no callback comes
  std::lock_guard lock(mutex_);
  tick_->set_done();
  WriteNextLocked();
}

void SkinReactor::OnFrameDone(StreamAnswer*) {
  {
    std::lock_guard lock(mutex_);
    answer_->set_done();
    WriteNextLocked();
  }
  Unref();
}

void SkinReactor::OnPartsReady(StreamAnswer*) {
  std::lock_guard lock(mutex_);
  WriteNextLocked();
}

void SkinReactor::OnWriteDone(bool ok) {
  std::lock_guard lock(mutex_);
  writing_ = false;
  answer_->PartWritten();
  if (!ok) {
    FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
    return;
  }
  WriteNextLocked();
}

void SkinReactor::OnDone() {
  {
    std::lock_guard lock(mutex_);
    answer_->DropWire();  // a frame cut off mid-way holds its buffer
  }
  Unref();
}

void SkinReactor::OnCancel() {
  std::lock_guard lock(mutex_);
  FinishLocked(grpc::Status::CANCELLED);
}

void SkinReactor::WriteNextLocked() {
  if (finished_ || writing_) return;
  // A failed frame's status ends the call (after an early part still being written).
  if (answer_->done() && !answer_->status().ok()) {
    FinishLocked(ToGrpc(answer_->status()));
    return;
  }
  bool last = false;
  if (const grpc::ByteBuffer* part = answer_->NextPart(&last)) {
    writing_ = true;
    StartWrite(part);
  } else if (answer_->done()) {  // every part written (early parts: else more are coming)
    FinishLocked(grpc::Status::OK);
  }
}

void SkinReactor::FinishLocked(const grpc::Status& status) {
  if (finished_) return;
  finished_ = true;
  Finish(status);
}

void SkinReactor::Unref() {
  if (refs_.fetch_sub(1) == 1) delete this;
}

}  // namespace skinserve::server
