#include "skin_reactor.h"

#include "engine_messages.h"
#include "skin_request_reader.h"

namespace skinserve::server {

SkinReactor::SkinReactor(Engine* engine, const std::string& default_backend,
                         const grpc::ByteBuffer& request_bytes, InflightBudget* budget,
                         RegionCaller regions)
    : job_(static_cast<FrameJob::Listener*>(this), budget) {
  grpc::ByteBuffer bytes(request_bytes);  // reading consumes it
  Status status = Unavailable("the server is starting: backends are being built");
  RegionHandle region;  // one frame: resolved for it alone
  if (engine != nullptr) {
    // Held (and charged) only until the job took what it keeps.
    SkinRequestReader reader(budget, {.max_instances = engine->options().max_instances});
    status = reader.Read(&bytes);
    status = status.ok()
                 ? job_.Prepare(reader.request(), *engine, default_backend, regions, &region)
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

void SkinReactor::OnFrameDone(FrameJob*) {
  {
    std::lock_guard lock(mutex_);
    job_.set_done();
    WriteNextLocked();
  }
  Unref();
}

void SkinReactor::OnPartsReady(FrameJob*) {
  std::lock_guard lock(mutex_);
  WriteNextLocked();
}

void SkinReactor::OnWriteDone(bool ok) {
  std::lock_guard lock(mutex_);
  writing_ = false;
  job_.PartWritten();
  if (!ok) {
    FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
    return;
  }
  WriteNextLocked();
}

void SkinReactor::OnDone() {
  {
    std::lock_guard lock(mutex_);
    job_.DropWire();  // a frame cut off mid-way holds its buffer
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
  if (job_.done() && !job_.status().ok()) {
    FinishLocked(ToGrpc(job_.status()));
    return;
  }
  bool last = false;
  if (const grpc::ByteBuffer* part = job_.NextPart(&last)) {
    writing_ = true;
    StartWrite(part);
  } else if (job_.done()) {  // every part written (early parts: else more are coming)
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
