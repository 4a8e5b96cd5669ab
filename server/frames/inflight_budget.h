// InflightBudget: the bytes that frames in flight may hold across all streams (their
// palettes, skinned vertices and encoded answers, i.e. each stream's reusable frame
// buffers). A frame that would take the total beyond the budget is refused with
// RESOURCE_EXHAUSTED naming the budget, so slow or hostile readers cannot grow the
// process without limit; the memory returns when their streams end.
// Uploads have a budget of their own, a second instance worded for them (OpenUploads).
#pragma once

#include <atomic>
#include <cstdint>

#include "skinserve/model/status.h"

namespace skinserve::server {

// What a refusal says: which budget, who asked and who holds it, the flag that sets it
// and what the client can do.
struct BudgetWording {
  const char* budget;
  const char* asker;
  const char* holders;
  const char* flag;
  const char* advice;
};

inline constexpr BudgetWording kFrameBudgetWording{
    "in-flight", "this frame", "frames in flight", "--inflight-budget-mb",
    "read answers sooner, keep fewer frames in flight or retry later"};

class InflightBudget {
 public:
  explicit InflightBudget(uint64_t limit_bytes, const BudgetWording& wording = kFrameBudgetWording)
      : limit_(limit_bytes), wording_(wording) {}

  // Takes `bytes` from the budget, or refuses (RESOURCE_EXHAUSTED) and takes nothing.
  Status TryCharge(uint64_t bytes);
  void Release(uint64_t bytes) { used_.fetch_sub(bytes); }

  uint64_t limit() const { return limit_; }
  uint64_t used() const { return used_.load(); }
  uint64_t refused() const { return refused_.load(); }

 private:
  const uint64_t limit_;
  const BudgetWording wording_;
  std::atomic<uint64_t> used_{0};
  std::atomic<uint64_t> refused_{0};
};

}  // namespace skinserve::server
