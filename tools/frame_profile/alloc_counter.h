// The counters of alloc_counter.c (see there). Plain C: the shim has no C++ runtime.
#pragma once

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

struct skinserve_alloc_counts {
  uint64_t allocations;  // malloc, calloc, realloc, aligned allocations
  uint64_t frees;
  uint64_t bytes;  // asked for, in total
};

// This process's counters (in the shared file when SKINSERVE_ALLOC_COUNTERS named one).
const struct skinserve_alloc_counts* skinserve_alloc_counters(void);

#ifdef __cplusplus
}
#endif
