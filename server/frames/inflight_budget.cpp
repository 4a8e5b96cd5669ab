#include "frames/inflight_budget.h"

#include <fmt/format.h>

#include <algorithm>
#include <string>

namespace skinserve::server {

Status InflightBudget::TryCharge(uint64_t bytes) {
  uint64_t used = used_.load();
  do {
    if (bytes > limit_ || used > limit_ - bytes) {
      refused_.fetch_add(1);
      return ResourceExhausted(fmt::format(
          "the {} budget is spent: {} needs {:.1f} MiB more and {} hold {:.1f} of {:.1f} MiB "
          "({} {}); {}",
          wording_.budget, wording_.asker, bytes / 1048576.0, wording_.holders, used / 1048576.0,
          limit_ / 1048576.0, wording_.flag, limit_ >> 20, wording_.advice));
    }
  } while (!used_.compare_exchange_weak(used, used + bytes));
  return Status::Ok();
}

}  // namespace skinserve::server
