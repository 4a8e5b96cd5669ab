// glibc malloc settings for a process that receives frames all the time. By default glibc
// serves each multi-hundred-KB block (gRPC's receive buffer of a frame) with its own mmap
// and gives it back on free, or trims the heap top: every frame then faults its pages in
// again (22 minor faults and ~28% of the client's CPU per 25k-vertex frame, measured with
// skinserve-frame-profile; docs/serving/frame-profile.md). Serving blocks up to 32 MiB from
// the heap and trimming only above 256 MiB keeps them mapped and reused. At most two
// arenas: with glibc's default (8 per core) each new stream's threads start a fresh arena
// and fault in all its buffers again, a stall of about a second when many streams open.
#pragma once

namespace skinserve::client {

// mallopt(M_MMAP_THRESHOLD, 32 MiB), mallopt(M_TRIM_THRESHOLD, 256 MiB) and
// mallopt(M_ARENA_MAX, 2); false if glibc refused any. Call once at start-up, before threads
// allocate.
bool TuneMallocForStreaming();

}  // namespace skinserve::client
