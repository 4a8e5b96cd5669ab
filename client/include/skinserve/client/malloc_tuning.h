// glibc malloc settings for a process that receives frames all the time. By default glibc
// serves each multi-hundred-KB block (gRPC's receive buffer of a frame) with its own mmap
// and gives it back on free, or trims the heap top: every frame then faults its pages in
// again (22 minor faults and ~28% of the client's CPU per 25k-vertex frame, measured with
// skinserve-frame-profile; README, "Per-frame profile"). Serving blocks up to 32 MiB from
// the heap and trimming only above 256 MiB keeps them mapped and reused.
#pragma once

namespace skinserve::client {

// mallopt(M_MMAP_THRESHOLD, 32 MiB) and mallopt(M_TRIM_THRESHOLD, 256 MiB); false if glibc
// refused either. Call once at start-up, before threads allocate.
bool TuneMallocForStreaming();

}  // namespace skinserve::client
