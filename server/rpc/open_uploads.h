// OpenUploads: the UploadMesh calls in progress and what they may hold. A new upload is
// admitted only below the caps: --max-uploads over all connections and
// --max-uploads-per-connection per client connection (keyed by the peer address gRPC
// reports, one per TCP connection), so that a few clients cannot take every slot. Their
// arrays are charged to the upload budget (--upload-budget-mb) as their chunks arrive
// (see MeshAssembly). A watchdog ends an upload that makes no progress (no header, no
// array bytes: empty chunks do not count) for --upload-idle-seconds, and one still open
// --upload-deadline-seconds after it was admitted however it progresses, so a stalled,
// dripping or hostile client holds neither a slot nor what it sent for longer than that.
// Every refusal is RESOURCE_EXHAUSTED naming the limit.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <unordered_map>

#include "frames/inflight_budget.h"
#include "skinserve/model/status.h"
#include "threads/periodic_thread.h"

namespace skinserve::server {

class MeshUploadReactor;

inline constexpr BudgetWording kUploadBudgetWording{
    "upload", "this upload", "open uploads", "--upload-budget-mb",
    "send fewer or smaller meshes at once, or retry later"};

struct UploadLimits {
  std::size_t max_uploads = 16;
  std::size_t max_uploads_per_connection = 4;
  uint64_t budget_bytes = 1ull << 30;
  double idle_seconds = 10;
  double deadline_seconds = 300;
};

// Which limit, if any, the watchdog ended an upload for.
enum class UploadOverdue { kNo, kIdle, kDeadline };

// For GetServerStats and /metrics.
struct UploadStats {
  uint64_t budget_bytes = 0;
  uint64_t bytes = 0;  // charged to the budget now
  uint64_t open = 0;
  uint64_t refused_max_uploads = 0;
  uint64_t refused_per_connection = 0;
  uint64_t refused_budget = 0;
  uint64_t cancelled_idle = 0;
  uint64_t cancelled_deadline = 0;
};

class OpenUploads {
 public:
  explicit OpenUploads(const UploadLimits& limits);
  ~OpenUploads();  // stops the watchdog; every upload has ended by then
  OpenUploads(const OpenUploads&) = delete;
  OpenUploads& operator=(const OpenUploads&) = delete;

  // Registers `upload` from connection `peer`, or says (RESOURCE_EXHAUSTED) which cap is
  // reached; then the upload should end at once with that status.
  Status Add(MeshUploadReactor* upload, const std::string& peer);
  void Remove(MeshUploadReactor* upload);

  InflightBudget* budget() { return &budget_; }
  UploadStats Stats() const;

 private:
  void EndOverdueUploads();  // the watchdog's round

  const UploadLimits limits_;
  const std::chrono::nanoseconds idle_limit_;
  const std::chrono::nanoseconds deadline_;
  InflightBudget budget_;
  mutable std::mutex mutex_;
  std::unordered_map<MeshUploadReactor*, std::string> uploads_;  // to their peer
  std::unordered_map<std::string, std::size_t> per_peer_;
  uint64_t refused_max_uploads_ = 0;
  uint64_t refused_per_connection_ = 0;
  uint64_t cancelled_idle_ = 0;
  uint64_t cancelled_deadline_ = 0;
  PeriodicThread watchdog_;  // last: it uses every member above, and stops first
};

}  // namespace skinserve::server
