#include "rpc/mesh_upload_reactor.h"

#include <spdlog/spdlog.h>

#include "rpc/server_messages.h"

namespace skinserve::server {

MeshUploadReactor::MeshUploadReactor(Engine* engine, OpenUploads* uploads, const std::string& peer,
                                     v1::MeshInfo* response)
    : uploads_(uploads), assembly_(engine, uploads->budget()), response_(response) {
  if (engine == nullptr) {
    std::lock_guard lock(mutex_);
    FinishLocked(ToGrpc(Unavailable("the server is starting: backends are being built")));
    return;
  }
  const Status admitted = uploads_->Add(this, peer);
  registered_ = admitted.ok();
  std::lock_guard lock(mutex_);
  if (!admitted.ok()) {
    FinishLocked(ToGrpc(admitted));
  } else {
    ReadLocked();
  }
}

void MeshUploadReactor::OnReadDone(bool ok) {
  {
    std::lock_guard lock(mutex_);
    reading_ = false;
    if (finished_) return;  // ended meanwhile (idle, cancelled): OnDone frees what it holds
  }
  // The message is handled outside the lock, so the watchdog never waits on a big copy
  // or a store; it leaves an upload alone while reading_ is false.
  // !ok: the client finished sending (or went away: then Finish goes nowhere).
  const uint64_t progress = assembly_.progress();
  const Status status = ok ? assembly_.Accept(message_) : Store();
  if (assembly_.progress() != progress) {
    progress_at_.store(std::chrono::steady_clock::now().time_since_epoch().count());
  }
  if (!status.ok()) assembly_.Discard();  // drop everything received so far
  // A waiting upload holds its (charged) arrays and nothing more: not its last chunk.
  message_.clear_part();
  std::lock_guard lock(mutex_);
  if (!ok || !status.ok()) {
    FinishLocked(ToGrpc(status));
  } else {
    ReadLocked();
  }
}

void MeshUploadReactor::OnCancel() {
  std::lock_guard lock(mutex_);
  FinishLocked(grpc::Status::CANCELLED);
}

void MeshUploadReactor::OnDone() {
  if (registered_) uploads_->Remove(this);  // only if it never finished (not expected)
  assembly_.Discard();                      // now, not when the last Hold lets go
  Unref();
}

UploadOverdue MeshUploadReactor::EndIfOverdue(std::chrono::steady_clock::time_point idle_cutoff,
                                              std::chrono::steady_clock::time_point deadline_cutoff,
                                              const Status& idle, const Status& deadline) {
  std::lock_guard lock(mutex_);
  if (finished_ || !reading_) return UploadOverdue::kNo;
  if (admitted_at_ <= deadline_cutoff) {
    FinishLocked(ToGrpc(deadline));
    return UploadOverdue::kDeadline;
  }
  if (progress_at() <= idle_cutoff) {
    FinishLocked(ToGrpc(idle));
    return UploadOverdue::kIdle;
  }
  return UploadOverdue::kNo;
}

Status MeshUploadReactor::Store() {
  auto info = assembly_.Store();
  if (!info.ok()) return info.status();
  *response_ = ToWire(*info);
  spdlog::info("mesh {} stored: {} vertices, {} influences, {} joints{}", info->id,
               info->vertex_count, info->influences, info->joint_count,
               info->already_stored ? " (already stored)" : "");
  return Status::Ok();
}

void MeshUploadReactor::ReadLocked() {
  if (finished_) return;
  reading_ = true;
  StartRead(&message_);
}

void MeshUploadReactor::FinishLocked(const grpc::Status& status) {
  if (finished_) return;
  finished_ = true;
  // The slot is given back before the client can see the status: a client that starts its
  // next upload on that answer must find the slot free.
  if (registered_) {
    uploads_->Remove(this);
    registered_ = false;
  }
  Finish(status);
}

void MeshUploadReactor::Unref() {
  if (refs_.fetch_sub(1) == 1) delete this;
}

}  // namespace skinserve::server
