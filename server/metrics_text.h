// The Prometheus text exposition (format 0.0.4) of one server: the engine's counters and
// gauges, the per-frame histograms and error counts, the open streams and the build.
#pragma once

#include <cstddef>
#include <map>
#include <string>

#include "metrics_frames.h"
#include "open_uploads.h"
#include "skinserve/engine/engine.h"

namespace skinserve::server {

struct MetricsSnapshot {
  std::string version;
  bool serving = false;  // false while starting and while draining
  std::size_t open_streams = 0;
  UploadStats uploads;
  EngineStats engine;  // empty while starting
  std::map<std::string, BackendFrameMetrics> frames;
};

std::string RenderPrometheusText(const MetricsSnapshot& snapshot);

}  // namespace skinserve::server
