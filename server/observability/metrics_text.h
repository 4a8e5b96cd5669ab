// The Prometheus text exposition (format 0.0.4) of a ServerSnapshot: the same facts as
// GetServerStats (server_snapshot.h), as counters, gauges and histograms.
#pragma once

#include <string>

#include "observability/server_snapshot.h"

namespace skinserve::server {

std::string RenderPrometheusText(const ServerSnapshot& snapshot);

}  // namespace skinserve::server
