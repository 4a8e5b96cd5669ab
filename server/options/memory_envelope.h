// MemoryEnvelope: everything clients can make the server hold, added up against the memory
// the process may use (the container's cgroup limit, else the machine's memory). Each
// budget counts with the copies it does not see itself: a stored mesh also lives in the
// backends' prepared copies (PoCL's buffers are host memory; simd copies joints and
// weights), an upload's arrays are still held while the mesh is built from them, and a
// region's tmpfs pages that the server's writes fault in are charged to its cgroup. The
// process's own footprint (code, gRPC, PoCL, stacks) comes first. Budgets left at 0 share
// what the given ones leave; the server does not start when the sum does not fit.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::server {

// The share of the memory the envelope may fill: the rest is slack for the allocator's
// free lists, the kernel's buffers and what no budget can see.
inline constexpr double kEnvelopeShareOfMemory = 0.9;
// The process at rest with every backend built (108-150 MB measured on the 2-core VM on
// 2026-11-28, RSS of a server that has served frames) and PoCL compiling a kernel.
inline constexpr uint64_t kProcessFootprintBytes = 256ull << 20;

struct EnvelopeTerm {
  std::string what;           // "stored meshes"
  std::string flag;           // "--mesh-budget-mb"
  uint64_t budget_bytes = 0;  // given, or derived when the flag was 0
  bool derived = false;
  double copies = 1;  // bytes held per byte of budget, at most
  double share = 0;   // of what is left, when derived
  std::string why;    // the copies the budget does not count
  uint64_t held_bytes() const { return static_cast<uint64_t>(budget_bytes * copies); }
};

struct MemoryEnvelope {
  uint64_t memory_bytes = 0;  // what the process may use
  std::string memory_source;  // "cgroup memory.max", "--memory-limit-mb", "physical memory"
  uint64_t footprint_bytes = kProcessFootprintBytes;
  std::vector<EnvelopeTerm> terms;

  uint64_t limit_bytes() const {
    return static_cast<uint64_t>(static_cast<double>(memory_bytes) * kEnvelopeShareOfMemory);
  }
  uint64_t sum_bytes() const;  // the footprint and every term's held bytes
  const EnvelopeTerm& term(const std::string& flag) const;
  // INVALID_ARGUMENT naming each term and the sum when it does not fit.
  Status Check() const;
  // One line per term, the sum and the limit: for the start-up log and --memory-envelope.
  std::string Describe() const;
};

// The memory this process may use: `limit_mb` when given, else the cgroup's limit, else
// physical memory.
MemoryEnvelope EnvelopeMemory(uint64_t limit_mb);

// Fills each term with budget 0 with its share of what the footprint and the given terms
// leave of the limit (at least 16 MiB each).
void DeriveBudgets(MemoryEnvelope* envelope);

}  // namespace skinserve::server
