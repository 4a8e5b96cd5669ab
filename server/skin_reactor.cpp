#include "skin_reactor.h"

#include "wire_codec.h"

namespace skinserve::server {

SkinReactor::SkinReactor(Engine* engine, const std::string& default_backend,
                         const v1::SkinRequest& request) {
  SkinRequest engine_request;
  Status status = engine == nullptr
                      ? Unavailable("the server is starting: backends are being built")
                      : job_.Prepare(request, *engine, default_backend, &engine_request);
  if (status.ok()) {
    refs_.fetch_add(1);
    status = engine->Submit(std::move(engine_request),
                            [this](Status s, FrameTiming t) { OnFrameDone(std::move(s), t); });
    if (!status.ok()) refs_.fetch_sub(1);  // refused: the engine will not call back
  }
  if (!status.ok()) {
    job_.Complete(status, {});  // the frame's verdict (for the metrics)
    std::lock_guard lock(mutex_);
    FinishLocked(ToGrpc(status));
  }
}

void SkinReactor::OnFrameDone(Status status, FrameTiming timing) {
  {
    std::lock_guard lock(mutex_);
    job_.Complete(std::move(status), timing);
    if (!job_.status().ok()) {
      FinishLocked(ToGrpc(job_.status()));
    } else {
      WriteNextLocked();
    }
  }
  Unref();
}

void SkinReactor::OnWriteDone(bool ok) {
  std::lock_guard lock(mutex_);
  if (!ok) {
    FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the client went away"));
    return;
  }
  WriteNextLocked();
}

void SkinReactor::OnCancel() {
  std::lock_guard lock(mutex_);
  FinishLocked(grpc::Status::CANCELLED);
}

void SkinReactor::WriteNextLocked() {
  if (finished_) return;
  if (job_.NextPart(&part_)) {
    StartWrite(&part_);
  } else {
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
