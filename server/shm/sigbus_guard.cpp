#include "shm/sigbus_guard.h"

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
// Where faults outside the ranges go. The original is what the first Install found (a
// sanitizer's handler, or the default action). A foreign handler is one another library put
// over the guard's later (PoCL's LLVM, when it compiles a kernel): Install publishes it in
// the slot the handler is not reading, so the handler never sees half a struct.
struct sigaction g_original;
bool g_has_original = false;  // under g_install_mutex
struct sigaction g_foreign[2];
std::atomic<int> g_foreign_slot{-1};  // -1: none
std::mutex g_install_mutex;           // Install only, never the handler

void OnSigbus(int signal, siginfo_t* info, void* context);

bool IsCallable(const struct sigaction& action) {
  if (action.sa_flags & SA_SIGINFO) {
    return action.sa_sigaction != nullptr && action.sa_sigaction != &OnSigbus;
  }
  return action.sa_handler != SIG_DFL && action.sa_handler != SIG_IGN &&
         action.sa_handler != nullptr;
}

bool SameHandler(const struct sigaction& a, const struct sigaction& b) {
  return (a.sa_flags & SA_SIGINFO) == (b.sa_flags & SA_SIGINFO) &&
         ((a.sa_flags & SA_SIGINFO) ? a.sa_sigaction == b.sa_sigaction
                                    : a.sa_handler == b.sa_handler);
}

bool IsGuard(const struct sigaction& action) {
  return (action.sa_flags & SA_SIGINFO) && action.sa_sigaction == &OnSigbus;
}

bool GuardIsInstalled() {
  struct sigaction now = {};
  return sigaction(SIGBUS, nullptr, &now) == 0 && IsGuard(now);
}

void Call(const struct sigaction& action, int signal, siginfo_t* info, void* context) {
  if (action.sa_flags & SA_SIGINFO) {
    action.sa_sigaction(signal, info, context);
  } else {
    action.sa_handler(signal);
  }
}

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
  // Not ours. First the foreign handler, if any, then the original. A handler that returns
  // may have changed the disposition: LLVM's puts back the handlers it replaced and returns
  // for the fault to rerun. If what it put back is not this one (ASan's, installed before
  // LLVM's), the rerun goes there. If it is this one, the chain goes on; at its end the
  // default action, so the rerun kills the process with a core dump instead of coming back
  // here for ever.
  const int slot = g_foreign_slot.load(std::memory_order_acquire);
  const struct sigaction* foreign = slot < 0 ? nullptr : &g_foreign[slot];
  if (foreign != nullptr && IsCallable(*foreign)) {
    Call(*foreign, signal, info, context);
    if (!GuardIsInstalled()) return;
  }
  if (IsCallable(g_original) && (foreign == nullptr || !SameHandler(*foreign, g_original))) {
    Call(g_original, signal, info, context);
    if (!GuardIsInstalled()) return;
  }
  struct sigaction fallback = {};
  fallback.sa_handler = SIG_DFL;
  sigaction(SIGBUS, &fallback, nullptr);
}

}  // namespace

void SigbusGuard::Install() {
  // Another library may have put its own handler over this one since (PoCL's LLVM
  // registers its crash handlers when it compiles a kernel, and one of them restored the
  // default action on a fault in a guarded range: the server died of the SIGBUS the guard
  // exists for). Then the one found is the first that faults outside the ranges go to,
  // before the original one.
  std::lock_guard lock(g_install_mutex);
  struct sigaction current = {};
  if (sigaction(SIGBUS, nullptr, &current) == 0 && IsGuard(current)) return;
  if (!g_has_original) {
    g_original = current;
    g_has_original = true;
  } else {
    // Publish into the slot the handler is not reading.
    const int next = g_foreign_slot.load(std::memory_order_relaxed) == 0 ? 1 : 0;
    g_foreign[next] = current;
    g_foreign_slot.store(next, std::memory_order_release);
  }
  struct sigaction action = {};
  action.sa_sigaction = &OnSigbus;
  action.sa_flags = SA_SIGINFO | SA_ONSTACK;
  sigemptyset(&action.sa_mask);
  sigaction(SIGBUS, &action, nullptr);
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
