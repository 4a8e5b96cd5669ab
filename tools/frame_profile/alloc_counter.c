// Counts a process's heap allocations (malloc, calloc, realloc, the aligned ones, and
// through them C++'s operator new) and forwards each to glibc's own allocator (__libc_*).
// Preloaded into a server (LD_PRELOAD) or linked into a client ahead of libc. The counters
// live in a file mapped shared when SKINSERVE_ALLOC_COUNTERS names one, so that another
// process (the profiler) reads them; else in this process's memory.
#include "alloc_counter.h"

#include <errno.h>
#include <fcntl.h>
#include <stddef.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

extern void* __libc_malloc(size_t size);
extern void __libc_free(void* p);
extern void* __libc_calloc(size_t n, size_t size);
extern void* __libc_realloc(void* p, size_t size);
extern void* __libc_memalign(size_t alignment, size_t size);

static struct skinserve_alloc_counts local_counts;
static struct skinserve_alloc_counts* counts = &local_counts;

__attribute__((constructor)) static void MapCountersFile(void) {
  const char* path = getenv("SKINSERVE_ALLOC_COUNTERS");
  if (path == NULL || *path == '\0') return;
  const int fd = open(path, O_RDWR | O_CREAT, 0600);
  if (fd < 0) return;
  if (ftruncate(fd, sizeof(struct skinserve_alloc_counts)) == 0) {
    void* shared = mmap(NULL, sizeof(struct skinserve_alloc_counts), PROT_READ | PROT_WRITE,
                        MAP_SHARED, fd, 0);
    if (shared != MAP_FAILED) counts = (struct skinserve_alloc_counts*)shared;
  }
  close(fd);
}

static inline void Count(size_t size) {
  __atomic_fetch_add(&counts->allocations, 1, __ATOMIC_RELAXED);
  __atomic_fetch_add(&counts->bytes, size, __ATOMIC_RELAXED);
}

const struct skinserve_alloc_counts* skinserve_alloc_counters(void) { return counts; }

void* malloc(size_t size) {
  Count(size);
  return __libc_malloc(size);
}

void free(void* p) {
  if (p != NULL) __atomic_fetch_add(&counts->frees, 1, __ATOMIC_RELAXED);
  __libc_free(p);
}

void* calloc(size_t n, size_t size) {
  Count(n * size);
  return __libc_calloc(n, size);
}

void* realloc(void* p, size_t size) {
  Count(size);
  if (p != NULL) __atomic_fetch_add(&counts->frees, 1, __ATOMIC_RELAXED);
  return __libc_realloc(p, size);
}

void* memalign(size_t alignment, size_t size) {
  Count(size);
  return __libc_memalign(alignment, size);
}

void* aligned_alloc(size_t alignment, size_t size) {
  Count(size);
  return __libc_memalign(alignment, size);
}

int posix_memalign(void** out, size_t alignment, size_t size) {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  Count(size);
  void* p = __libc_memalign(alignment, size);
  if (p == NULL) return ENOMEM;
  *out = p;
  return 0;
}

void* valloc(size_t size) {
  Count(size);
  return __libc_memalign((size_t)sysconf(_SC_PAGESIZE), size);
}
