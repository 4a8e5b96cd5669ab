#include "observability/metrics_text.h"

#include <fmt/format.h>

#include <iterator>

namespace skinserve::server {

namespace {

// Label values escape backslash, double quote and newline.
std::string Escape(const std::string& value) {
  std::string out;
  for (char c : value) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

// Shortest text that reads back as the same double ("0.00025", not "0.000250000").
std::string Number(double v) { return fmt::format("{}", v); }

class Writer {
 public:
  void Header(const char* name, const char* type, const char* help) {
    fmt::format_to(std::back_inserter(out_), "# HELP {} {}\n# TYPE {} {}\n", name, help, name,
                   type);
  }
  void Sample(const char* name, const std::string& labels, double value) {
    fmt::format_to(std::back_inserter(out_), "{}{}{}{} {}\n", name, labels.empty() ? "" : "{",
                   labels, labels.empty() ? "" : "}", Number(value));
  }
  void Sample(const std::string& name, const std::string& labels, double value) {
    Sample(name.c_str(), labels, value);
  }
  void Histogram(const char* name, const std::string& labels, const DurationHistogram& h) {
    uint64_t cumulative = 0;
    for (std::size_t i = 0; i < h.kBounds.size(); ++i) {
      cumulative += h.buckets[i];
      Sample(fmt::format("{}_bucket", name),
             fmt::format("{},le=\"{}\"", labels, Number(h.kBounds[i])),
             static_cast<double>(cumulative));
    }
    Sample(fmt::format("{}_bucket", name), fmt::format("{},le=\"+Inf\"", labels),
           static_cast<double>(h.count));
    Sample(fmt::format("{}_sum", name), labels, h.sum_seconds);
    Sample(fmt::format("{}_count", name), labels, static_cast<double>(h.count));
  }
  std::string Take() { return std::move(out_); }

 private:
  std::string out_;
};

std::string BackendLabel(const std::string& id) {
  return fmt::format("backend=\"{}\"", Escape(id));
}

// Which build runs, and whether it takes calls.
void WriteBuildAndServing(Writer& w, const ServerSnapshot& s) {
  w.Header("skinserve_build_info", "gauge", "Always 1; the labels say which build runs.");
  w.Sample("skinserve_build_info", fmt::format("version=\"{}\"", Escape(s.version)), 1);
  w.Header("skinserve_serving", "gauge",
           "1 while the server takes new calls; 0 while it starts (backends being built) or "
           "drains.");
  w.Sample("skinserve_serving", "", s.serving ? 1 : 0);
}

// Per backend: frames, vertices, compute time and errors; then the ticks.
void WriteBackendCounters(Writer& w, const ServerSnapshot& s) {
  const EngineStats& e = s.engine;
  w.Header("skinserve_frames_total", "counter", "Frames skinned, by backend.");
  for (const BackendStats& b : e.backends) {
    w.Sample("skinserve_frames_total", BackendLabel(b.id), static_cast<double>(b.frames));
  }
  w.Header("skinserve_vertices_total", "counter", "Vertices skinned, by backend.");
  for (const BackendStats& b : e.backends) {
    w.Sample("skinserve_vertices_total", BackendLabel(b.id), static_cast<double>(b.vertices));
  }
  w.Header("skinserve_compute_seconds_total", "counter",
           "Time the backend spent skinning frames, by backend.");
  for (const BackendStats& b : e.backends) {
    w.Sample("skinserve_compute_seconds_total", BackendLabel(b.id),
             static_cast<double>(b.compute_ns_total) * 1e-9);
  }
  w.Header("skinserve_backend_errors_total", "counter",
           "Frames that failed inside the engine (after it took them), by backend.");
  for (const BackendStats& b : e.backends) {
    w.Sample("skinserve_backend_errors_total", BackendLabel(b.id), static_cast<double>(b.errors));
  }
  w.Header("skinserve_frame_errors_total", "counter",
           "Frames answered with an error, by backend and gRPC status code.");
  for (const auto& [backend, f] : s.frames) {
    for (const auto& [code, n] : f.errors_by_code) {
      w.Sample("skinserve_frame_errors_total",
               fmt::format("{},code=\"{}\"", BackendLabel(backend), code), static_cast<double>(n));
    }
  }
  w.Header("skinserve_ticks_total", "counter",
           "Ticks read (requests with SkinRequest.characters), refused ones included.");
  w.Sample("skinserve_ticks_total", "", static_cast<double>(s.ticks.ticks));
  w.Header("skinserve_tick_characters_total", "counter",
           "Characters of the ticks read; each is also counted as a frame of its backend.");
  w.Sample("skinserve_tick_characters_total", "", static_cast<double>(s.ticks.characters));
}

// Per backend: where answered frames' time went.
void WriteFrameHistograms(Writer& w, const ServerSnapshot& s) {
  struct Histo {
    const char* name;
    const char* help;
    DurationHistogram BackendFrameMetrics::*member;
  };
  const Histo histograms[] = {
      {"skinserve_frame_queue_seconds",
       "Time answered frames waited in the engine's queue for a compute thread.",
       &BackendFrameMetrics::queue},
      {"skinserve_frame_compute_seconds", "Time the backend took to skin answered frames.",
       &BackendFrameMetrics::compute},
      {"skinserve_frame_encode_seconds",
       "Time spent writing answered frames' vertices into response messages.",
       &BackendFrameMetrics::encode},
      {"skinserve_frame_server_seconds",
       "Time from reading a frame's request to producing its last response part (answered "
       "and failed frames).",
       &BackendFrameMetrics::server},
  };
  for (const Histo& h : histograms) {
    w.Header(h.name, "histogram", h.help);
    for (const auto& [backend, f] : s.frames)
      w.Histogram(h.name, BackendLabel(backend), f.*h.member);
  }
}

// Open streams, and the uploads in progress with their memory and refusals.
void WriteStreamsAndUploads(Writer& w, const ServerSnapshot& s) {
  w.Header("skinserve_open_streams", "gauge", "StreamSkin calls in progress.");
  w.Sample("skinserve_open_streams", "", static_cast<double>(s.open_streams));
  w.Header("skinserve_streams_ended_idle_total", "counter",
           "StreamSkin calls the server ended for sending nothing with no frame in flight "
           "(--stream-idle-seconds).");
  w.Sample("skinserve_streams_ended_idle_total", "", static_cast<double>(s.streams_ended_idle));
  w.Header("skinserve_frame_socket_connections", "gauge",
           "Frame-socket connections open (--frame-socket).");
  w.Sample("skinserve_frame_socket_connections", "",
           static_cast<double>(s.frame_socket.connections));
  w.Header("skinserve_frame_socket_refused_total", "counter",
           "Frame-socket connections refused over --frame-socket-max-connections.");
  w.Sample("skinserve_frame_socket_refused_total", "", static_cast<double>(s.frame_socket.refused));
  w.Header("skinserve_frame_socket_requests_total", "counter",
           "Requests (frames and ticks) read on the frame socket.");
  w.Sample("skinserve_frame_socket_requests_total", "",
           static_cast<double>(s.frame_socket.requests));
  const UploadStats& u = s.uploads;
  w.Header("skinserve_open_uploads", "gauge", "UploadMesh calls in progress.");
  w.Sample("skinserve_open_uploads", "", static_cast<double>(u.open));
  w.Header("skinserve_upload_bytes", "gauge",
           "Memory held by the arrays of uploads in progress (charged to the upload budget).");
  w.Sample("skinserve_upload_bytes", "", static_cast<double>(u.bytes));
  w.Header("skinserve_upload_budget_bytes", "gauge",
           "Memory uploads in progress may hold together; beyond, a chunk ends its upload.");
  w.Sample("skinserve_upload_budget_bytes", "", static_cast<double>(u.budget_bytes));
  w.Header("skinserve_upload_refusals_total", "counter",
           "Uploads refused or ended, by the limit: max_uploads, max_uploads_per_connection, "
           "upload_budget, upload_idle, upload_deadline.");
  const std::pair<const char*, uint64_t> refusals[] = {
      {"max_uploads", u.refused_max_uploads},
      {"max_uploads_per_connection", u.refused_per_connection},
      {"upload_budget", u.refused_budget},
      {"upload_idle", u.cancelled_idle},
      {"upload_deadline", u.cancelled_deadline}};
  for (const auto& [reason, n] : refusals) {
    w.Sample("skinserve_upload_refusals_total", fmt::format("reason=\"{}\"", reason),
             static_cast<double>(n));
  }
}

// The engine: stored meshes, its queue and its threads; then the frames in flight.
void WriteEngineAndInflight(Writer& w, const ServerSnapshot& s) {
  const EngineStats& e = s.engine;
  w.Header("skinserve_meshes", "gauge", "Meshes stored.");
  w.Sample("skinserve_meshes", "", static_cast<double>(e.meshes));
  w.Header("skinserve_mesh_bytes", "gauge", "Memory held by stored meshes.");
  w.Sample("skinserve_mesh_bytes", "", static_cast<double>(e.mesh_bytes));
  w.Header("skinserve_mesh_budget_bytes", "gauge",
           "Memory meshes may hold before the least recently used are evicted.");
  w.Sample("skinserve_mesh_budget_bytes", "", static_cast<double>(e.mesh_budget_bytes));
  w.Header("skinserve_mesh_evictions_total", "counter", "Meshes evicted to stay in the budget.");
  w.Sample("skinserve_mesh_evictions_total", "", static_cast<double>(e.evictions));
  w.Header("skinserve_queue_depth", "gauge", "Frames waiting for a compute thread.");
  w.Sample("skinserve_queue_depth", "", static_cast<double>(e.queue_depth));
  w.Header("skinserve_queue_capacity", "gauge",
           "Frames that may wait; beyond, frames are refused (RESOURCE_EXHAUSTED).");
  w.Sample("skinserve_queue_capacity", "", static_cast<double>(e.queue_capacity));
  w.Header("skinserve_queue_rejections_total", "counter",
           "Frames refused because the queue was full.");
  w.Sample("skinserve_queue_rejections_total", "", static_cast<double>(e.rejected_queue_full));
  w.Header("skinserve_peak_busy_threads", "gauge",
           "The most compute threads ever skinning at once (never above the compute threads).");
  w.Sample("skinserve_peak_busy_threads", "", static_cast<double>(e.peak_busy_threads));
  w.Header("skinserve_inline_frames_total", "counter",
           "Frames skinned on the thread that read them (no compute thread was worth waking).");
  w.Sample("skinserve_inline_frames_total", "", static_cast<double>(e.inline_frames));
  w.Header("skinserve_frame_plans_total", "counter",
           "Frames planned with a lookup of mesh and backend (built) or on their stream's kept "
           "plan (reused).");
  w.Sample("skinserve_frame_plans_total", "kind=\"built\"", static_cast<double>(e.plans_built));
  w.Sample("skinserve_frame_plans_total", "kind=\"reused\"", static_cast<double>(e.plans_reused));
  w.Header("skinserve_inflight_bytes", "gauge",
           "Memory frames in flight hold (every stream's frame buffers).");
  w.Sample("skinserve_inflight_bytes", "", static_cast<double>(s.inflight.bytes));
  w.Header("skinserve_inflight_budget_bytes", "gauge",
           "Memory frames in flight may hold; beyond, frames are refused (RESOURCE_EXHAUSTED).");
  w.Sample("skinserve_inflight_budget_bytes", "", static_cast<double>(s.inflight.budget_bytes));
  w.Header("skinserve_inflight_rejections_total", "counter",
           "Frames refused for want of in-flight budget.");
  w.Sample("skinserve_inflight_rejections_total", "", static_cast<double>(s.inflight.refused));
}

// The shared-memory regions (when shared memory is on).
void WriteRegions(Writer& w, const ServerSnapshot& s) {
  if (s.shared_memory) {
    const RegionStats& r = s.regions;
    w.Header("skinserve_regions", "gauge", "Shared-memory regions registered.");
    w.Sample("skinserve_regions", "", static_cast<double>(r.regions));
    w.Header("skinserve_region_bytes", "gauge", "Bytes the registered regions map.");
    w.Sample("skinserve_region_bytes", "", static_cast<double>(r.mapped_bytes));
    w.Header("skinserve_region_budget_bytes", "gauge",
             "Bytes the regions may map together (--shm-budget-mb).");
    w.Sample("skinserve_region_budget_bytes", "", static_cast<double>(r.budget_bytes));
    w.Header("skinserve_region_frames_total", "counter",
             "Frames written into shared-memory regions.");
    w.Sample("skinserve_region_frames_total", "", static_cast<double>(r.frames));
    w.Header("skinserve_region_rejections_total", "counter",
             "Registrations refused for a limit (budget, regions, per connection).");
    w.Sample("skinserve_region_rejections_total", "", static_cast<double>(r.rejected));
  }
}

// The animation store: skeletons and clips uploaded, and their budget.
void WriteAnimations(Writer& w, const ServerSnapshot& s) {
  const AnimationStoreStats& a = s.animations;
  w.Header("skinserve_skeletons", "gauge", "Skeletons stored (UploadSkeleton).");
  w.Sample("skinserve_skeletons", "", static_cast<double>(a.skeletons));
  w.Header("skinserve_clips", "gauge", "Animation clips stored (UploadClip).");
  w.Sample("skinserve_clips", "", static_cast<double>(a.clips));
  w.Header("skinserve_clip_bytes", "gauge", "Bytes the stored skeletons and clips are charged.");
  w.Sample("skinserve_clip_bytes", "", static_cast<double>(a.bytes));
  w.Header("skinserve_clip_budget_bytes", "gauge",
           "Bytes skeletons and clips may be charged together (--clip-budget-mb).");
  w.Sample("skinserve_clip_budget_bytes", "", static_cast<double>(a.budget_bytes));
}

}  // namespace

std::string RenderPrometheusText(const ServerSnapshot& s) {
  Writer w;
  WriteBuildAndServing(w, s);
  WriteBackendCounters(w, s);
  WriteFrameHistograms(w, s);
  WriteStreamsAndUploads(w, s);
  WriteEngineAndInflight(w, s);
  WriteRegions(w, s);
  WriteAnimations(w, s);
  // Last: a scrape that ends with it is whole (tests/ops/metrics-test.sh checks that).
  w.Header("skinserve_compute_threads", "gauge", "Compute threads skinning frames.");
  w.Sample("skinserve_compute_threads", "", static_cast<double>(s.engine.compute_threads));
  return w.Take();
}

}  // namespace skinserve::server
