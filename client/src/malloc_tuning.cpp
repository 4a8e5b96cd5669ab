#include "skinserve/client/malloc_tuning.h"

#include <malloc.h>

namespace skinserve::client {

bool TuneMallocForStreaming() {
  constexpr int kMmapThreshold = 32 << 20;  // glibc's largest (HEAP_MAX_SIZE / 2 on 64-bit)
  constexpr int kTrimThreshold = 256 << 20;
  // Two arenas, not glibc's 8 per core: every new thread otherwise gets a fresh arena whose
  // frame buffers all fault in anew, and a load client opening 16 streams (32 threads)
  // stalled every stream for ~1 s (p99 77-114 ms) while they did; with 2, p99 4-8 ms.
  constexpr int kArenaMax = 2;
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, kTrimThreshold) == 1;
  const bool arenas_ok = mallopt(M_ARENA_MAX, kArenaMax) == 1;
  return mmap_ok && trim_ok && arenas_ok;
}

}  // namespace skinserve::client
