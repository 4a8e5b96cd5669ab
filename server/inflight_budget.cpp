#include "inflight_budget.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
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

uint64_t InflightBudget::DefaultLimitBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page_size = sysconf(_SC_PAGE_SIZE);
  uint64_t memory = pages > 0 && page_size > 0 ? uint64_t(pages) * uint64_t(page_size) : 4ull << 30;
  std::ifstream cgroup("/sys/fs/cgroup/memory.max");  // cgroup v2; "max" when unlimited
  std::string limit;
  if (cgroup >> limit && limit != "max") {
    try {
      memory = std::min<uint64_t>(memory, std::stoull(limit));
    } catch (const std::exception&) {  // unreadable: keep physical memory
    }
  }
  return std::max<uint64_t>(memory / 4, 64ull << 20);
}

}  // namespace skinserve::server
