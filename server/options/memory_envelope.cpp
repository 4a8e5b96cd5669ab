#include "options/memory_envelope.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <stdexcept>

#include "options/cgroup_limits.h"

namespace skinserve::server {
namespace {

constexpr uint64_t kMinDerivedBudgetBytes = 16ull << 20;

double MiB(uint64_t bytes) { return static_cast<double>(bytes) / (1 << 20); }

}  // namespace

MemoryEnvelope EnvelopeMemory(uint64_t limit_mb) {
  MemoryEnvelope envelope;
  if (limit_mb > 0) {
    envelope.memory_bytes = limit_mb << 20;
    envelope.memory_source = "--memory-limit-mb";
    return envelope;
  }
  const long pages = sysconf(_SC_PHYS_PAGES), page_size = sysconf(_SC_PAGE_SIZE);
  envelope.memory_bytes =
      pages > 0 && page_size > 0 ? uint64_t(pages) * uint64_t(page_size) : 4ull << 30;
  envelope.memory_source = "physical memory";
  if (const auto cgroup = ReadCgroupLimits().memory_bytes;
      cgroup && *cgroup < envelope.memory_bytes) {
    envelope.memory_bytes = *cgroup;
    envelope.memory_source = "the cgroup's memory limit";
  }
  return envelope;
}

void DeriveBudgets(MemoryEnvelope* envelope) {
  uint64_t given = envelope->footprint_bytes;
  double shares = 0;
  for (const EnvelopeTerm& t : envelope->terms) {
    if (t.budget_bytes > 0) {
      given += t.held_bytes();
    } else {
      shares += t.share;
    }
  }
  const uint64_t limit = envelope->limit_bytes();
  const uint64_t left = limit > given ? limit - given : 0;
  for (EnvelopeTerm& t : envelope->terms) {
    if (t.budget_bytes > 0 || shares <= 0) continue;
    const double bytes = static_cast<double>(left) * (t.share / shares) / t.copies;
    // Whole MiB, as the flags give them.
    t.budget_bytes = std::max(kMinDerivedBudgetBytes, static_cast<uint64_t>(bytes) >> 20 << 20);
    t.derived = true;
  }
}

uint64_t MemoryEnvelope::sum_bytes() const {
  uint64_t sum = footprint_bytes;
  for (const EnvelopeTerm& t : terms) sum += t.held_bytes();
  return sum;
}

const EnvelopeTerm& MemoryEnvelope::term(const std::string& flag) const {
  for (const EnvelopeTerm& t : terms) {
    if (t.flag == flag) return t;
  }
  throw std::logic_error("no memory envelope term for " + flag);
}

Status MemoryEnvelope::Check() const {
  if (sum_bytes() <= limit_bytes()) return Status::Ok();
  return InvalidArgument(fmt::format(
      "the budgets do not fit the memory: they can make the server hold {:.0f} MiB, more "
      "than {:.0f}% of the {:.0f} MiB it may use ({}); lower the budgets set by hand or leave "
      "them at 0 to share what is left. The envelope:\n{}",
      MiB(sum_bytes()), kEnvelopeShareOfMemory * 100, MiB(memory_bytes), memory_source,
      Describe()));
}

std::string MemoryEnvelope::Describe() const {
  std::string out = fmt::format("  {:<34} {:>9.0f} MiB\n", "the process itself (footprint)",
                                MiB(footprint_bytes));
  for (const EnvelopeTerm& t : terms) {
    out += fmt::format("  {:<34} {:>9.0f} MiB = {} {:.0f} MiB{} x {:g} ({})\n", t.what,
                       MiB(t.held_bytes()), t.flag, MiB(t.budget_bytes),
                       t.derived ? " (derived)" : "", t.copies, t.why);
  }
  out += fmt::format("  {:<34} {:>9.0f} MiB of {:.0f} MiB ({:.0f}% of {:.0f} MiB, {})", "sum",
                     MiB(sum_bytes()), MiB(limit_bytes()), kEnvelopeShareOfMemory * 100,
                     MiB(memory_bytes), memory_source);
  return out;
}

}  // namespace skinserve::server
