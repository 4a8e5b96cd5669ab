#include "sigbus_guard.h"

#include <signal.h>
#include <sys/mman.h>

#include <cstdint>
#include <mutex>

namespace skinserve::server {
namespace {

// A guarded range. The handler reads the slots lock-free (only atomics, no allocation);
// Add and Remove change them under a mutex. `begin` is 0 while a slot is free or being
// filled: the handler skips it.
struct Slot {
  std::atomic<uintptr_t> begin{0};
  std::atomic<std::size_t> size{0};
  std::atomic<std::atomic<bool>*> broken{nullptr};
};

Slot g_slots[SigbusGuard::kMaxRanges];
std::mutex g_slots_mutex;  // Add and Remove only, never the handler
struct sigaction g_previous;
std::mutex g_install_mutex;  // Install only, never the handler

void OnSigbus(int signal, siginfo_t* info, void* context) {
  const auto address = reinterpret_cast<uintptr_t>(info->si_addr);
  for (Slot& slot : g_slots) {
    const uintptr_t begin = slot.begin.load(std::memory_order_acquire);
    if (begin == 0 || address < begin) continue;
    const std::size_t size = slot.size.load(std::memory_order_relaxed);
    if (address - begin >= size) continue;
    // Anonymous pages over the whole range: the faulting write is retried there, and so
    // is every later write of the frame. mmap is not on POSIX's async-signal-safe list,
    // but it is a plain system call on Linux (libwayland does the same).
    void* replaced = mmap(reinterpret_cast<void*>(begin), size, PROT_READ | PROT_WRITE,
                          MAP_FIXED | MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (replaced == MAP_FAILED) break;  // cannot recover: fall through to the default
    if (std::atomic<bool>* broken = slot.broken.load(std::memory_order_relaxed)) {
      broken->store(true, std::memory_order_release);
    }
    return;
  }
  // Not ours: what was there before (e.g. a sanitizer's report), else the default action.
  // A handler that returns (LLVM's puts back what it replaced, this one, and returns for
  // the fault to rerun) gets the default action after it: the rerun kills the process
  // instead of coming back here for ever.
  if ((g_previous.sa_flags & SA_SIGINFO) && g_previous.sa_sigaction != nullptr &&
      g_previous.sa_sigaction != &OnSigbus) {
    g_previous.sa_sigaction(signal, info, context);
  } else if (!(g_previous.sa_flags & SA_SIGINFO) && g_previous.sa_handler != SIG_DFL &&
             g_previous.sa_handler != SIG_IGN && g_previous.sa_handler != nullptr) {
    g_previous.sa_handler(signal);
  }
  // Returning re-runs the faulting access, which now kills the process with a core dump.
  struct sigaction fallback = {};
  fallback.sa_handler = SIG_DFL;
  sigaction(SIGBUS, &fallback, nullptr);
}

}  // namespace

void SigbusGuard::Install() {
  // Another library may have put its own handler over this one since (PoCL's LLVM
  // registers its crash handlers when it compiles a kernel, and one of them restored the
  // default action on a fault in a guarded range: the server died of the SIGBUS the guard
  // exists for). Then the one found becomes the one faults outside the ranges go to.
  std::lock_guard lock(g_install_mutex);
  struct sigaction current = {};
  if (sigaction(SIGBUS, nullptr, &current) == 0 && (current.sa_flags & SA_SIGINFO) &&
      current.sa_sigaction == &OnSigbus) {
    return;
  }
  struct sigaction action = {};
  action.sa_sigaction = &OnSigbus;
  action.sa_flags = SA_SIGINFO | SA_ONSTACK;
  sigemptyset(&action.sa_mask);
  sigaction(SIGBUS, &action, &g_previous);
}

int SigbusGuard::Add(void* begin, std::size_t size, std::atomic<bool>* broken) {
  std::lock_guard lock(g_slots_mutex);
  for (std::size_t i = 0; i < kMaxRanges; ++i) {
    Slot& slot = g_slots[i];
    if (slot.begin.load(std::memory_order_relaxed) != 0) continue;
    slot.size.store(size, std::memory_order_relaxed);
    slot.broken.store(broken, std::memory_order_relaxed);
    slot.begin.store(reinterpret_cast<uintptr_t>(begin), std::memory_order_release);
    return static_cast<int>(i);
  }
  return -1;
}

void SigbusGuard::Remove(int slot) {
  if (slot < 0 || static_cast<std::size_t>(slot) >= kMaxRanges) return;
  std::lock_guard lock(g_slots_mutex);
  g_slots[slot].begin.store(0, std::memory_order_release);
  g_slots[slot].broken.store(nullptr, std::memory_order_relaxed);
}

}  // namespace skinserve::server
