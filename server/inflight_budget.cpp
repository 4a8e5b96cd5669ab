#include "inflight_budget.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <string>

#include "cgroup_limits.h"

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

uint64_t InflightBudget::DefaultLimitBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page_size = sysconf(_SC_PAGE_SIZE);
  uint64_t memory = pages > 0 && page_size > 0 ? uint64_t(pages) * uint64_t(page_size) : 4ull << 30;
  if (const auto limit = ReadCgroupLimits().memory_bytes) memory = std::min(memory, *limit);
  return std::max<uint64_t>(memory / 4, 64ull << 20);
}

}  // namespace skinserve::server
