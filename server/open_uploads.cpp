#include "open_uploads.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

#include "mesh_upload_reactor.h"

namespace skinserve::server {
namespace {

// How often the watchdog looks: a quarter of the idle limit, at most 250 ms, so an idle
// upload ends at most a quarter late.
std::chrono::nanoseconds WatchPeriod(std::chrono::nanoseconds idle_limit) {
  return std::clamp<std::chrono::nanoseconds>(idle_limit / 4, std::chrono::milliseconds(1),
                                              std::chrono::milliseconds(250));
}

}  // namespace

OpenUploads::OpenUploads(const UploadLimits& limits)
    : limits_(limits),
      idle_limit_(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double>(limits.idle_seconds))),
      budget_(limits.budget_bytes, kUploadBudgetWording),
      watchdog_([this] { Watch(); }) {}

OpenUploads::~OpenUploads() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  watchdog_.join();
}

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
          .cancelled_idle = cancelled_idle_};
}

void OpenUploads::Watch() {
  const auto period = WatchPeriod(idle_limit_);
  const Status idle = ResourceExhausted(fmt::format(
      "this upload sent nothing for {} s (--upload-idle-seconds {}) and was ended; nothing "
      "was stored: send the next message sooner, or start the upload again",
      limits_.idle_seconds, limits_.idle_seconds));
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, period, [&] { return stopping_; })) {
    const auto cutoff = std::chrono::steady_clock::now() - idle_limit_;
    // Ended outside our lock (an upload's OnDone takes it to remove itself); each is held
    // so that it outlives that call.
    std::vector<MeshUploadReactor*> idle_uploads;
    for (const auto& [upload, peer] : uploads_) {
      if (upload->waiting_since() <= cutoff) {
        upload->Hold();
        idle_uploads.push_back(upload);
      }
    }
    if (idle_uploads.empty()) continue;
    lock.unlock();
    uint64_t ended = 0;
    for (MeshUploadReactor* upload : idle_uploads) {
      if (upload->EndIfWaitingSince(cutoff, idle)) ++ended;
      upload->Release();
    }
    if (ended > 0) spdlog::debug("{} idle uploads ended (--upload-idle-seconds)", ended);
    lock.lock();
    cancelled_idle_ += ended;
  }
}

}  // namespace skinserve::server
