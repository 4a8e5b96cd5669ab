// SigbusGuard: makes writes into a client's shared-memory mapping safe against the client.
// A shared mapping of a file faults with SIGBUS where the file no longer has pages, and any
// client that can write its region's file can truncate it while a compute thread (or
// OpenCL's, or OpenMP's) is writing a frame there. The guard's handler catches such a
// fault inside a guarded range, maps anonymous memory over the whole range (so the write
// and every later one land in memory nobody reads) and marks the range broken; the frame
// then fails with a status naming the region. A SIGBUS anywhere else is left to the
// handler installed before (by default: the process dies with a core dump, as it should).
// This is the approach of Wayland compositors for clients' wl_shm pools.
#pragma once

#include <atomic>
#include <cstddef>

namespace skinserve::server {

class SigbusGuard {
 public:
  // The most ranges guarded at once (the server caps its regions below this).
  static constexpr std::size_t kMaxRanges = 4096;

  // Installs the process-wide handler; later calls put it back if another library has
  // replaced it since (the server calls it before every frame it writes into a region).
  static void Install();

  // Guards [begin, begin + size) (page-aligned, as mmap returns it) until Remove;
  // `broken` is set when a fault was caught in it. Returns the slot, or -1 when
  // kMaxRanges ranges are guarded already.
  static int Add(void* begin, std::size_t size, std::atomic<bool>* broken);
  // Stops guarding a slot; call before unmapping the range.
  static void Remove(int slot);
};

}  // namespace skinserve::server
