// The process_* series of Prometheus' client libraries (CPU seconds, resident and virtual
// memory, open and allowed file descriptors, start time), read from /proc/self on each
// scrape, plus skinserve_memory_limit_bytes: the cgroup memory limit the resident memory
// is held to (0: none), so an alert can compare the two.
#pragma once

#include <string>

namespace skinserve::server {

// The exposition text of those series. A value that cannot be read is left out (its HELP
// and TYPE stay), never written as 0.
std::string RenderProcessMetrics();

}  // namespace skinserve::server
