// The load client's measurement parts as units, against values worked out independently:
// arrival schedules (constant by formula, Poisson by its moments), rate ranges, the
// stability rule, the Prometheus text parser and deltas, merged windows, and the report's
// columns (CSV and JSON from one list).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "arrivals.h"
#include "load_report.h"
#include "load_stats.h"
#include "measurement_flags.h"
#include "report_columns.h"
#include "report_files.h"
#include "server_metrics.h"
#include "stability.h"

namespace skinserve::load {
namespace {

TEST(ArrivalScheduleTest, ConstantStaggersStreamsEvenly) {
  // 3 streams at 10 frames/s: stream s sends at (k + s/3) / 10 s, so together every 1/30 s.
  for (int s = 0; s < 3; ++s) {
    ArrivalSchedule schedule(Arrivals::kConstant, 10, s, 3, 1);
    for (int k = 0; k < 50; ++k) {
      EXPECT_NEAR(schedule.Next(), (k + s / 3.0) / 10.0, 1e-12) << "stream " << s << " k " << k;
    }
  }
}

TEST(ArrivalScheduleTest, PoissonGapsHaveTheExponentialsMomentsAndRepeatBySeed) {
  const double rate = 40;
  const int n = 40000;
  ArrivalSchedule schedule(Arrivals::kPoisson, rate, 1, 4, 7);
  std::vector<double> gaps;
  double previous = 0;
  for (int i = 0; i < n; ++i) {
    const double t = schedule.Next();
    ASSERT_GT(t, previous);
    gaps.push_back(t - previous);
    previous = t;
  }
  double sum = 0, below_mean = 0;
  for (double g : gaps) sum += g;
  const double mean = sum / n;
  double squares = 0;
  for (double g : gaps) {
    squares += (g - mean) * (g - mean);
    below_mean += g < 1 / rate;
  }
  const double cv = std::sqrt(squares / (n - 1)) / mean;
  // Exp(rate): mean 1/rate, CV 1, P(gap < mean) = 1 - 1/e. With 40000 gaps the standard
  // errors are ~0.5% (mean), ~0.7% (CV) and ~0.24% (fraction): 4 of them or more apart.
  EXPECT_NEAR(mean, 1 / rate, 0.03 / rate);
  EXPECT_NEAR(cv, 1.0, 0.04);
  EXPECT_NEAR(below_mean / n, 1 - std::exp(-1.0), 0.012);

  ArrivalSchedule again(Arrivals::kPoisson, rate, 1, 4, 7),
      other_seed(Arrivals::kPoisson, rate, 1, 4, 8),
      other_stream(Arrivals::kPoisson, rate, 2, 4, 7);
  EXPECT_DOUBLE_EQ(again.Next(), gaps[0]) << "the same seed and stream: the same schedule";
  EXPECT_NE(other_seed.Next(), gaps[0]);
  EXPECT_NE(other_stream.Next(), gaps[0]);
}

TEST(RateRangeTest, ListsEveryStepAndRefusesNonsense) {
  auto rates = ParseRateRange("10:30:10");
  ASSERT_TRUE(rates.ok());
  EXPECT_EQ(*rates, (std::vector<double>{10, 20, 30}));
  rates = ParseRateRange("0.5:1.6:0.5");
  ASSERT_TRUE(rates.ok());
  EXPECT_EQ(*rates, (std::vector<double>{0.5, 1.0, 1.5}));
  rates = ParseRateRange("3:5");
  ASSERT_TRUE(rates.ok());
  EXPECT_EQ(*rates, (std::vector<double>{3, 4, 5}));
  rates = ParseRateRange("0.1:0.3:0.1");  // 0.1 + 2 * 0.1 rounds above 0.3: still there
  ASSERT_TRUE(rates.ok());
  EXPECT_EQ(rates->size(), 3u);
  for (const char* bad : {"", "10", "10:", "a:20:5", "0:10:1", "20:10:1", "10:20:0", "10:20:-1",
                          "1:2:3:4", "1:100000:0.01"}) {
    const auto r = ParseRateRange(bad);
    EXPECT_FALSE(r.ok()) << bad;
    if (!r.ok()) {
      EXPECT_NE(r.status().message().find("--rate-range"), std::string::npos);
    }
  }
}

RunResult Window(uint64_t frames, double seconds, double latency_ms) {
  RunResult r;
  r.backend = "sse";
  r.frames = frames;
  r.sent = frames;
  r.seconds = seconds;
  r.latencies_ms.assign(frames, latency_ms);
  return r;
}

TEST(StabilityTest, TheLastThreeWindowsMustAgreeInThroughputAndLatency) {
  // 100, 104, 96 frames/s: mean 100, each within 4%; latency 10 ms each.
  std::vector<RunResult> w = {Window(50, 1, 30), Window(100, 1, 10), Window(104, 1, 10),
                              Window(96, 1, 10)};
  EXPECT_TRUE(LastWindowsAgree(w, 5, 99));
  EXPECT_FALSE(LastWindowsAgree(w, 3, 99)) << "104 is 4% off the mean";
  EXPECT_FALSE(LastWindowsAgree({w[1], w[2]}, 50, 99)) << "fewer than three windows";
  w.push_back(Window(100, 1, 12));  // 104, 96, 100 frames/s; 10, 10, 12 ms (mean 10.67)
  EXPECT_FALSE(LastWindowsAgree(w, 5, 99)) << "12 ms is 12.5% off the mean latency";
  EXPECT_TRUE(LastWindowsAgree(w, 13, 99));
}

// Errors are counted by code, and the first message of each code is kept (the table prints
// it under the rows), also across merged windows.
TEST(MergeResultsTest, KeepsTheFirstMessageOfEachErrorCode) {
  RunResult a, b;
  a.CountError(Internal("first internal"));
  a.CountError(Internal("second internal"));
  b.CountError(Internal("third internal"));
  b.CountError(NotFound("lost mesh"), 3);
  EXPECT_EQ(a.errors.at("INTERNAL"), 2u);
  EXPECT_EQ(a.error_examples.at("INTERNAL"), "first internal");
  const RunResult m = MergeResults({a, b});
  EXPECT_EQ(m.errors.at("INTERNAL"), 3u);
  EXPECT_EQ(m.errors.at("NOT_FOUND"), 3u);
  EXPECT_EQ(m.error_examples.at("INTERNAL"), "first internal");
  EXPECT_EQ(m.error_examples.at("NOT_FOUND"), "lost mesh");
}

TEST(MergeResultsTest, AddsCountsAndPoolsLatencies) {
  RunResult a = Window(10, 1, 5), b = Window(30, 2, 7);
  a.errors["UNAVAILABLE"] = 1;
  b.errors["UNAVAILABLE"] = 2;
  b.errors["INTERNAL"] = 1;
  a.metrics_scraped = b.metrics_scraped = true;
  a.server_metrics["x"] = 3;
  b.server_metrics["x"] = 4;
  b.server_metrics["y"] = 1;
  a.transport_ms_sum = 2;
  b.transport_ms_sum = 6;
  const RunResult m = MergeResults({a, b});
  EXPECT_EQ(m.frames, 40u);
  EXPECT_DOUBLE_EQ(m.seconds, 3);
  EXPECT_DOUBLE_EQ(m.frames_per_second(), 40.0 / 3);
  EXPECT_EQ(m.latencies_ms.size(), 40u);
  EXPECT_DOUBLE_EQ(Summarize(m.latencies_ms, 50).at_percentile, 7);  // 30 of 40 are 7 ms
  EXPECT_EQ(m.errors.at("UNAVAILABLE"), 3u);
  EXPECT_EQ(m.errors.at("INTERNAL"), 1u);
  EXPECT_DOUBLE_EQ(m.server_metrics.at("x"), 7);
  EXPECT_DOUBLE_EQ(m.server_metrics.at("y"), 1);
  EXPECT_DOUBLE_EQ(m.mean(m.transport_ms_sum), 0.2);
}

// Server CPU per frame and per character, and over compute, worked out by hand: 0.05 s of
// CPU over the 200 frames of 4 characters each the server answered is 250 us a frame, 62.5
// a character; a compute column of 25 us a frame makes it 10 times compute. The client's
// own count (190 frames) is not the divisor: its measured part is not the scrapes' window.
TEST(ServerCpuTest, PerFramePerCharacterAndOverComputeFromHandPickedNumbers) {
  RunResult r = Window(190, 1, 5);
  r.instances = 4;
  r.server_compute_ms_sum = 190 * 0.025;
  r.server_frames = 200;
  EXPECT_FALSE(r.server_cpu_us_per_frame()) << "not scraped: no number made up";
  EXPECT_FALSE(r.server_cpu_us_per_character());
  EXPECT_FALSE(r.server_cpu_over_compute());
  r.server_cpu_seconds = 0.05;
  EXPECT_DOUBLE_EQ(*r.server_cpu_us_per_frame(), 250);
  EXPECT_DOUBLE_EQ(*r.server_cpu_us_per_character(), 62.5);
  EXPECT_DOUBLE_EQ(*r.server_cpu_over_compute(), 10);
  r.server_compute_ms_sum = 0;
  EXPECT_FALSE(r.server_cpu_over_compute()) << "no compute to compare with";
  RunResult none = Window(190, 1, 5);
  none.server_cpu_seconds = 0.05;
  EXPECT_FALSE(none.server_cpu_us_per_frame()) << "the server answered no frames";

  // Merged windows: CPU seconds and frames added (0.05 + 0.03 over 200 + 100 frames), or
  // none when a window lacks the CPU.
  RunResult more = Window(90, 1, 5);
  more.instances = 4;
  more.server_frames = 100;
  more.server_cpu_seconds = 0.03;
  r.server_cpu_seconds = 0.05;
  EXPECT_DOUBLE_EQ(*MergeResults({r, more}).server_cpu_us_per_frame(), 0.08e6 / 300);
  more.server_cpu_seconds.reset();
  EXPECT_FALSE(MergeResults({r, more}).server_cpu_seconds);
}

TEST(ServerCpuTest, CpuSecondsBetweenScrapesOnlyWhenBothHoldIt) {
  const MetricSamples before = {{"process_cpu_seconds_total", 12.5}, {"other_total", 1}};
  const MetricSamples after = {{"process_cpu_seconds_total", 12.75}, {"other_total", 9}};
  EXPECT_DOUBLE_EQ(*CpuSecondsBetween(before, after), 0.25);
  EXPECT_DOUBLE_EQ(*CpuSecondsBetween(before, before), 0) << "no CPU spent is 0, not none";
  EXPECT_FALSE(CpuSecondsBetween({{"other_total", 1}}, after)) << "an older server";
  EXPECT_FALSE(CpuSecondsBetween(before, {{"other_total", 9}}));
  EXPECT_FALSE(CpuSecondsBetween(after, before)) << "went down: a restart";
  // As the server writes it (a counter), the parser keeps it.
  auto parsed = ParseMetricsText(
      "# HELP process_cpu_seconds_total Total user and system CPU time spent in seconds.\n"
      "# TYPE process_cpu_seconds_total counter\nprocess_cpu_seconds_total 3.41\n");
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  EXPECT_NEAR(*CpuSecondsBetween({{"process_cpu_seconds_total", 3}}, *parsed), 0.41, 1e-12);
}

// The text table: the server CPU columns, in their places, only when a row knows its CPU.
TEST(ServerCpuTest, TextTableShowsTheColumnsWhenScraped) {
  RunResult r = Window(200, 1, 5);
  r.instances = 4;
  r.server_compute_ms_sum = 200 * 0.025;
  r.server_frames = 200;
  ::testing::internal::CaptureStdout();
  PrintTable({r}, false);
  std::fflush(stdout);
  const std::string bare = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(bare.find("cpu us/fr"), std::string::npos) << bare;
  r.server_cpu_seconds = 0.05;
  ::testing::internal::CaptureStdout();
  PrintTable({r}, false);
  std::fflush(stdout);
  const std::string text = ::testing::internal::GetCapturedStdout();
  EXPECT_NE(text.find("cpu us/fr  cpu us/ch cpu/comp errors\n"), std::string::npos) << text;
  EXPECT_NE(text.find("      250.0       62.5    10.00 0\n"), std::string::npos) << text;
}

TEST(SendGapTest, CoefficientOfVariationOfHandPickedGaps) {
  RunResult r;
  for (double g : {10.0, 20.0, 30.0}) {  // mean 20, sample sd 10: CV 0.5
    ++r.send_gaps;
    r.send_gap_ms_sum += g;
    r.send_gap_ms_sq_sum += g * g;
  }
  EXPECT_DOUBLE_EQ(r.send_gap_mean_ms(), 20);
  EXPECT_NEAR(r.send_gap_cv(), 0.5, 1e-12);
}

TEST(MetricsTextTest, ParsesTheExpositionFormatRobustly) {
  const std::string text =
      "# HELP skinserve_frames_total Frames skinned, by backend.\n"
      "# TYPE skinserve_frames_total counter\n"
      "skinserve_frames_total{backend=\"sse\"} 120\n"
      "skinserve_frames_total{backend=\"passthrough\"} 2 1700000000000\n"
      "\n"
      "# TYPE skinserve_open_streams gauge\n"
      "skinserve_open_streams 3\n"
      "# TYPE odd_total counter\n"
      "odd_total{b=\"x, y\",a=\"say \\\"hi\\\" {}\"}   4.5e1\n"
      "# TYPE h_seconds histogram\n"
      "h_seconds_bucket{backend=\"sse\",le=\"+Inf\"} 7\n"
      "h_seconds_sum{backend=\"sse\"} 0.25\n"
      "h_seconds_count{backend=\"sse\"} 7\n"
      "untyped_thing NaN\r\n"
      "inf_total +Inf\n";
  auto samples = ParseMetricsText(text);
  ASSERT_TRUE(samples.ok()) << samples.status().ToString();
  const MetricSamples& m = *samples;
  EXPECT_DOUBLE_EQ(m.at("skinserve_frames_total{backend=\"sse\"}"), 120);
  EXPECT_DOUBLE_EQ(m.at("skinserve_frames_total{backend=\"passthrough\"}"), 2);
  EXPECT_EQ(m.count("skinserve_open_streams"), 0u) << "a gauge's difference means nothing";
  EXPECT_DOUBLE_EQ(m.at("odd_total{a=\"say \\\"hi\\\" {}\",b=\"x, y\"}"), 45);
  EXPECT_EQ(m.count("h_seconds_bucket{backend=\"sse\",le=\"+Inf\"}"), 0u) << "buckets left out";
  EXPECT_DOUBLE_EQ(m.at("h_seconds_count{backend=\"sse\"}"), 7);
  EXPECT_DOUBLE_EQ(m.at("h_seconds_sum{backend=\"sse\"}"), 0.25);
  EXPECT_TRUE(std::isnan(m.at("untyped_thing")));
  EXPECT_TRUE(std::isinf(m.at("inf_total")));
  EXPECT_DOUBLE_EQ(SumSeries(m, "skinserve_frames_total"), 122);
  EXPECT_DOUBLE_EQ(SumSeries(m, "skinserve_frames_total", {"backend=\"sse\""}), 120);
  EXPECT_DOUBLE_EQ(SumSeries(m, "h_seconds_sum", {"backend=\"sse\""}), 0.25);

  for (const auto& [bad, line] :
       std::vector<std::pair<std::string, int>>{{"a 1\n{x=\"1\"} 2\n", 2},
                                                {"a 1\nb 2\nc{x=\"1\" 3\n", 3},
                                                {"c{x=1} 3\n", 1},
                                                {"c{x=\"1} 3\n", 1},
                                                {"c{x=\"1\"} three\n", 1},
                                                {"c\n", 1}}) {
    const auto r = ParseMetricsText(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.status().message().find("line " + std::to_string(line)), std::string::npos)
        << r.status().message();
  }
}

TEST(MetricsTextTest, DeltasCountNewSeriesFromZeroAndResetsFromTheirValue) {
  const MetricSamples before = {{"a", 10}, {"b", 5}, {"same", 3}};
  const MetricSamples after = {{"a", 25}, {"b", 2}, {"new", 4}, {"same", 3}};
  const MetricSamples d = MetricDeltas(before, after);
  EXPECT_DOUBLE_EQ(d.at("a"), 15);
  EXPECT_DOUBLE_EQ(d.at("b"), 2) << "went down: the server restarted, counted from 0";
  EXPECT_DOUBLE_EQ(d.at("new"), 4);
  EXPECT_EQ(d.count("same"), 0u);
}

TEST(MetricsTextTest, ScrapeRefusesBadUrlsNamingThem) {
  for (const char* url : {"https://x/metrics", "127.0.0.1:9/metrics", "http://:80/", "http://h:x/",
                          "http://h:99999/"}) {
    const auto r = ScrapeMetrics(url, 1);
    ASSERT_FALSE(r.ok()) << url;
    EXPECT_NE(r.status().message().find(url), std::string::npos) << r.status().message();
  }
  EXPECT_FALSE(ScrapeMetrics("http://127.0.0.1:1/metrics", 1).ok()) << "nothing listens there";
}

TEST(ReportColumnsTest, CsvAndJsonHoldTheSameColumnsAndValues) {
  RunResult serial = Window(40, 2, 8), sse = Window(100, 2, 3);
  serial.backend = "serial";
  sse.encoding = "snorm16";
  sse.instances = 4;
  sse.rate = 50;
  sse.streams = 2;
  sse.arrivals = "poisson";
  sse.errors["RESOURCE_EXHAUSTED"] = 2;
  sse.latency_limit_ms = 2.5;
  sse.stable = true;
  sse.trials = 4;
  sse.metrics_scraped = true;
  sse.server_metrics["skinserve_frames_total{backend=\"sse\"}"] = 100;
  sse.server_metrics["skinserve_frame_errors_total{backend=\"sse\",code=\"RESOURCE_EXHAUSTED\"}"] =
      2;
  sse.server_metrics["skinserve_frames_total{backend=\"passthrough\"}"] = 2;
  sse.server_cpu_seconds = 0.06;  // over 100 frames of 4: 600 us a frame, 150 a character
  sse.server_frames = 100;
  sse.server_compute_ms_sum = 100 * 0.2;
  sse.pose = true;  // --animate FILE: the clip's name
  sse.clip = "Anim_0";
  const std::vector<RunResult> results = {serial, sse};
  const std::string base = ::testing::TempDir() + "columns-" + std::to_string(getpid());
  ASSERT_TRUE(WriteCsv(base + ".csv", results).ok());
  ASSERT_TRUE(WriteJson(base + ".json", results).ok());
  ExpectCsvMatchesJson(base + ".csv", base + ".json");

  std::ifstream in(base + ".json");
  nlohmann::json doc;
  in >> doc;
  const auto& row = doc["results"][1];
  // Worked out by hand from the rows above.
  EXPECT_DOUBLE_EQ(row["frames_per_second"].get<double>(), 50);
  EXPECT_DOUBLE_EQ(row["characters_per_second"].get<double>(), 200);
  EXPECT_DOUBLE_EQ(row["offered_frames_per_second"].get<double>(), 100);
  EXPECT_DOUBLE_EQ(row["speedup_over_serial"].get<double>(), 50.0 / 20);
  EXPECT_EQ(row["within_limit"], false) << "3 ms at p99 is over 2.5 ms";
  EXPECT_EQ(row["encoding"], "snorm16");
  EXPECT_EQ(row["instances"], 4);
  EXPECT_DOUBLE_EQ(row["server_metrics"]["frames"].get<double>(), 100) << "sse's series only";
  EXPECT_DOUBLE_EQ(row["server_metrics"]["frame_errors"].get<double>(), 2);
  EXPECT_TRUE(doc["results"][0]["server_metrics"]["frames"].is_null()) << "not scraped";
  EXPECT_DOUBLE_EQ(row["server_cpu_us_per_frame"].get<double>(), 600);
  EXPECT_DOUBLE_EQ(row["server_cpu_us_per_character"].get<double>(), 150);
  EXPECT_DOUBLE_EQ(row["server_cpu_over_compute"].get<double>(), 3);
  EXPECT_DOUBLE_EQ(row["server_cpu_seconds"].get<double>(), 0.06);
  EXPECT_DOUBLE_EQ(row["server_frames"].get<double>(), 100);
  for (const char* column : {"server_cpu_us_per_frame", "server_cpu_us_per_character",
                             "server_cpu_over_compute", "server_cpu_seconds", "server_frames"}) {
    EXPECT_TRUE(doc["results"][0][column].is_null()) << column << ": not scraped, left empty";
  }
  EXPECT_TRUE(doc["results"][0]["stable"].is_null()) << "no stability rule applied";
  EXPECT_EQ(row["clip"], "Anim_0");
  EXPECT_TRUE(doc["results"][0]["clip"].is_null()) << "palettes: no clip";
}

}  // namespace
}  // namespace skinserve::load
