// The server's two report surfaces come from one snapshot: after frames on several backends
// (good and failed), an upload, a shared-memory region and a refused frame, every fact of
// GetServerStats is on /metrics with the same value, and the other way round for every
// metric family /metrics serves.
#include <httplib.h>

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "skinserve/client/shared_memory_region.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

// "name{labels}" -> value, from Prometheus' text format.
std::map<std::string, double> ParseMetrics(const std::string& text) {
  std::map<std::string, double> samples;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t space = line.rfind(' ');
    samples[line.substr(0, space)] = std::strtod(line.c_str() + space + 1, nullptr);
  }
  return samples;
}

TEST(StatsSurfacesTest, GetServerStatsAndMetricsShowTheSameSnapshot) {
  char dir_name[] = "/dev/shm/skinserve-stats-XXXXXX";
  const std::string dir = mkdtemp(dir_name);
  server::ServerOptions options;
  options.metrics_listen = "127.0.0.1:0";
  options.shm_dir = dir;
  options.backends = {"serial", "simd", "passthrough"};
  options.default_backend = "simd";
  TestServer t(options, Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 3000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const auto palette = MakeSyntheticPalette(77, 1, 1);
  client::FrameResult result;
  for (const char* backend : {"serial", "simd", "simd", "passthrough"}) {
    ASSERT_TRUE(t.client->Skin(info->mesh_id(), backend, palette, 1, false, &result).ok());
  }
  auto region = client::SharedMemoryRegion::Create(
      client::SharedMemoryRegion::UniqueKey("stats"),
      wire::RegionFrameBytes(3000, 1, VertexEncoding::kFloat32, false), dir);
  ASSERT_TRUE(region.ok());
  ASSERT_TRUE(t.client->RegisterRegion("stats", **region).ok());
  ASSERT_TRUE(t.client
                  ->Skin(info->mesh_id(), palette, 2,
                         {.backend = "simd", .output = {.name = "stats", .region = region->get()}},
                         &result)
                  .ok());
  // A frame the engine refuses (short palette) and one it never sees (unknown region).
  EXPECT_FALSE(
      t.client->Skin(info->mesh_id(), "simd", std::span(palette).first(12), 3, false, &result)
          .ok());
  EXPECT_FALSE(t.client
                   ->Skin(info->mesh_id(), palette, 4,
                          {.backend = "simd", .output = {.name = "none", .region = region->get()}},
                          &result)
                   .ok());

  // A frame's buffers stay charged until gRPC drops its last slice, which may be just after
  // the client has its answer: the two surfaces are read once that gauge is back at rest,
  // so that nothing changes between the two reads.
  auto stats = t.client->GetServerStats();
  for (int i = 0; i < 500 && stats.ok() && stats->inflight_bytes() != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    stats = t.client->GetServerStats();
  }
  ASSERT_TRUE(stats.ok()) << stats.status().ToString();
  ASSERT_EQ(stats->inflight_bytes(), 0u) << "frames still in flight 5 s after their answers";
  httplib::Client http("127.0.0.1", t.server->metrics_port());
  auto scraped = http.Get("/metrics");
  ASSERT_TRUE(scraped && scraped->status == 200);
  const auto m = ParseMetrics(scraped->body);

  std::set<std::string> families_checked;
  const auto expect = [&](const std::string& sample, double value) {
    const std::string family = sample.substr(0, sample.find('{'));
    families_checked.insert(family);
    auto it = m.find(sample);
    ASSERT_NE(it, m.end()) << sample << " is not on /metrics";
    EXPECT_NEAR(it->second, value, 1e-6 * std::max(1.0, std::abs(value))) << sample;
  };
  expect("skinserve_build_info{version=\"" + stats->version() + "\"}", 1);
  expect("skinserve_serving", stats->serving() ? 1 : 0);
  EXPECT_TRUE(stats->serving());
  for (const auto& b : stats->backends()) {
    const std::string label = "{backend=\"" + b.id() + "\"}";
    expect("skinserve_frames_total" + label, b.frames());
    expect("skinserve_vertices_total" + label, b.vertices());
    expect("skinserve_compute_seconds_total" + label, b.compute_ns_total() * 1e-9);
    expect("skinserve_backend_errors_total" + label, b.errors());
    for (const auto& [code, n] : b.errors_by_code()) {
      expect("skinserve_frame_errors_total{backend=\"" + b.id() + "\",code=\"" + code + "\"}", n);
    }
    const std::pair<const char*, const v1::DurationHistogram*> histograms[] = {
        {"queue", &b.queue()},
        {"compute", &b.compute()},
        {"encode", &b.encode()},
        {"server", &b.server()}};
    for (const auto& [name, h] : histograms) {
      const std::string family = std::string("skinserve_frame_") + name + "_seconds";
      expect(family + "_count" + label, h->count());
      expect(family + "_sum" + label, h->sum_seconds());
      for (int i = 0; i < h->upper_bounds_size(); ++i) {
        std::ostringstream le;
        le << h->upper_bounds(i);
        expect(family + "_bucket{backend=\"" + b.id() + "\",le=\"" + le.str() + "\"}",
               h->bucket_counts(i));
      }
      families_checked.insert(family);
    }
  }
  EXPECT_EQ(stats->backends_size(), 3);
  // The per-frame histograms are process-wide (one /metrics per process): other tests in
  // this binary add to them, so only the engine's own counts are checked absolutely.
  for (const auto& b : stats->backends()) {
    if (b.id() == "simd") {
      EXPECT_EQ(b.frames(), 3u);
      EXPECT_GE(b.server().count(), 5u) << "answered and failed frames in the server histogram";
      EXPECT_GE(b.errors_by_code().at("INVALID_ARGUMENT"), 1u);
      EXPECT_GE(b.errors_by_code().at("FAILED_PRECONDITION"), 1u);
    }
  }
  expect("skinserve_open_streams", stats->open_streams());
  expect("skinserve_streams_ended_idle_total", stats->ended_streams_idle());
  expect("skinserve_frame_socket_connections", stats->frame_socket_connections());
  expect("skinserve_frame_socket_refused_total", stats->frame_socket_refused());
  expect("skinserve_frame_socket_requests_total", stats->frame_socket_requests());
  expect("skinserve_queue_depth", stats->queue_depth());
  expect("skinserve_queue_capacity", stats->queue_capacity());
  expect("skinserve_queue_rejections_total", stats->rejected_queue_full());
  expect("skinserve_compute_threads", stats->compute_threads());
  expect("skinserve_peak_busy_threads", stats->peak_busy_threads());
  EXPECT_GE(stats->peak_busy_threads(), 1);
  expect("skinserve_inline_frames_total", stats->inline_frames());
  expect("skinserve_frame_plans_total{kind=\"built\"}", stats->frame_plans_built());
  expect("skinserve_frame_plans_total{kind=\"reused\"}", stats->frame_plans_reused());
  // Each single Skin call is planned afresh (the five answered at least; the refused ones
  // may be too): a call has no stream plan to reuse.
  EXPECT_GE(stats->frame_plans_built(), 5u);
  EXPECT_EQ(stats->frame_plans_reused(), 0u);
  expect("skinserve_meshes", stats->meshes());
  expect("skinserve_mesh_bytes", stats->mesh_bytes());
  expect("skinserve_mesh_budget_bytes", stats->mesh_budget_bytes());
  expect("skinserve_mesh_evictions_total", stats->evictions());
  expect("skinserve_inflight_budget_bytes", stats->inflight_budget_bytes());
  expect("skinserve_inflight_bytes", stats->inflight_bytes());
  expect("skinserve_inflight_rejections_total", stats->rejected_inflight_budget());
  expect("skinserve_regions", stats->regions());
  EXPECT_EQ(stats->regions(), 1u);
  expect("skinserve_region_bytes", stats->region_bytes());
  expect("skinserve_region_budget_bytes", stats->region_budget_bytes());
  expect("skinserve_region_frames_total", stats->region_frames());
  EXPECT_EQ(stats->region_frames(), 1u);
  expect("skinserve_region_rejections_total", stats->rejected_regions());
  expect("skinserve_ticks_total", stats->ticks());
  expect("skinserve_tick_characters_total", stats->tick_characters());
  expect("skinserve_open_uploads", stats->open_uploads());
  expect("skinserve_upload_bytes", stats->upload_bytes());
  expect("skinserve_upload_budget_bytes", stats->upload_budget_bytes());
  expect("skinserve_upload_refusals_total{reason=\"max_uploads\"}",
         stats->rejected_uploads_max_uploads());
  expect("skinserve_upload_refusals_total{reason=\"max_uploads_per_connection\"}",
         stats->rejected_uploads_per_connection());
  expect("skinserve_upload_refusals_total{reason=\"upload_budget\"}",
         stats->rejected_uploads_budget());
  expect("skinserve_upload_refusals_total{reason=\"upload_idle\"}",
         stats->cancelled_uploads_idle());
  expect("skinserve_upload_refusals_total{reason=\"upload_deadline\"}",
         stats->cancelled_uploads_deadline());
  expect("skinserve_skeletons", stats->skeletons());
  expect("skinserve_clips", stats->clips());
  expect("skinserve_clip_bytes", stats->clip_bytes());
  expect("skinserve_clip_budget_bytes", stats->clip_budget_bytes());
  EXPECT_GT(stats->clip_budget_bytes(), 0u);

  // And the other way round: every family /metrics serves was compared above.
  std::set<std::string> families;
  for (const auto& [sample, value] : m) {
    std::string family = sample.substr(0, sample.find('{'));
    for (const char* suffix : {"_bucket", "_count", "_sum"}) {
      const std::string s(suffix);
      if (family.size() > s.size() && family.ends_with(s) &&
          family.find("_seconds") != std::string::npos && !family.ends_with("_seconds_total")) {
        family.resize(family.size() - s.size());
      }
    }
    families.insert(family);
  }
  for (const std::string& family : families) {
    // The process' own series (process_metrics.h) are facts of the process, not of the
    // service: on /metrics only, checked against /proc by tests/ops/process-metrics-test.py.
    if (family.starts_with("process_") || family == "skinserve_memory_limit_bytes" ||
        family == "skinserve_process_context_switches_total") {
      continue;
    }
    EXPECT_TRUE(families_checked.count(family)) << family << " is on /metrics only";
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace skinserve::testing
