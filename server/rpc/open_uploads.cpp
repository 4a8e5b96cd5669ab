#include "rpc/open_uploads.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

#include "rpc/mesh_upload_reactor.h"
#include "threads/watchdog_period.h"

namespace skinserve::server {
OpenUploads::OpenUploads(const UploadLimits& limits)
    : limits_(limits),
      idle_limit_(LimitNanoseconds(limits.idle_seconds)),
      deadline_(LimitNanoseconds(limits.deadline_seconds)),
      budget_(limits.budget_bytes, kUploadBudgetWording),
      watchdog_(WatchdogPeriod(std::min(idle_limit_, deadline_)), [this] { EndOverdueUploads(); }) {
}

OpenUploads::~OpenUploads() = default;

Status OpenUploads::Add(MeshUploadReactor* upload, const std::string& peer) {
  std::lock_guard lock(mutex_);
  if (uploads_.size() >= limits_.max_uploads) {
    ++refused_max_uploads_;
    return ResourceExhausted(fmt::format(
        "the server has {} uploads open, its limit (--max-uploads {}); nothing was stored: "
        "retry later or on another replica",
        uploads_.size(), limits_.max_uploads));
  }
  std::size_t& from_peer = per_peer_[peer];
  if (from_peer >= limits_.max_uploads_per_connection) {
    ++refused_per_connection_;
    return ResourceExhausted(fmt::format(
        "this connection has {} uploads open, its limit (--max-uploads-per-connection {}); "
        "nothing was stored: finish one first",
        from_peer, limits_.max_uploads_per_connection));
  }
  ++from_peer;
  uploads_.emplace(upload, peer);
  return Status::Ok();
}

void OpenUploads::Remove(MeshUploadReactor* upload) {
  std::lock_guard lock(mutex_);
  auto it = uploads_.find(upload);
  if (it == uploads_.end()) return;
  auto from_peer = per_peer_.find(it->second);
  if (--from_peer->second == 0) per_peer_.erase(from_peer);
  uploads_.erase(it);
}

UploadStats OpenUploads::Stats() const {
  std::lock_guard lock(mutex_);
  return {.budget_bytes = budget_.limit(),
          .bytes = budget_.used(),
          .open = uploads_.size(),
          .refused_max_uploads = refused_max_uploads_,
          .refused_per_connection = refused_per_connection_,
          .refused_budget = budget_.refused(),
          .cancelled_idle = cancelled_idle_,
          .cancelled_deadline = cancelled_deadline_};
}

void OpenUploads::EndOverdueUploads() {
  const auto now = std::chrono::steady_clock::now();
  const auto idle_cutoff = now - idle_limit_, deadline_cutoff = now - deadline_;
  // Ended outside our lock (an upload's OnDone takes it to remove itself); each is held so
  // that it outlives that call.
  std::vector<MeshUploadReactor*> overdue;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [upload, peer] : uploads_) {
      if (upload->progress_at() <= idle_cutoff || upload->admitted_at() <= deadline_cutoff) {
        upload->Hold();
        overdue.push_back(upload);
      }
    }
  }
  if (overdue.empty()) return;
  const Status idle = ResourceExhausted(fmt::format(
      "this upload made no progress for {} s, its limit (--upload-idle-seconds {}): neither "
      "its header nor array bytes arrived (empty chunks do not count); it was ended and "
      "nothing was stored: send the next chunk sooner, or start the upload again",
      limits_.idle_seconds, limits_.idle_seconds));
  const Status deadline = ResourceExhausted(fmt::format(
      "this upload was still open {} s after it began, its limit (--upload-deadline-seconds "
      "{}); it was ended and nothing was stored: send the mesh faster (larger chunks, no "
      "pauses), or ask the operator for a longer limit",
      limits_.deadline_seconds, limits_.deadline_seconds));
  uint64_t ended_idle = 0, ended_deadline = 0;
  for (MeshUploadReactor* upload : overdue) {
    switch (upload->EndIfOverdue(idle_cutoff, deadline_cutoff, idle, deadline)) {
      case UploadOverdue::kIdle:
        ++ended_idle;
        break;
      case UploadOverdue::kDeadline:
        ++ended_deadline;
        break;
      case UploadOverdue::kNo:
        break;
    }
    upload->Release();
  }
  if (ended_idle + ended_deadline > 0) {
    spdlog::debug(
        "uploads ended: {} idle (--upload-idle-seconds), {} past their deadline "
        "(--upload-deadline-seconds)",
        ended_idle, ended_deadline);
  }
  std::lock_guard lock(mutex_);
  cancelled_idle_ += ended_idle;
  cancelled_deadline_ += ended_deadline;
}

}  // namespace skinserve::server
