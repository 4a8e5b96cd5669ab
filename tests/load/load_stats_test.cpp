// The load client's arithmetic against values worked out by hand.
#include "load_stats.h"

#include <gtest/gtest.h>

namespace skinserve::load {
namespace {

TEST(LoadStatsTest, PercentilesInterpolateBetweenClosestRanks) {
  std::vector<double> v = {40, 10, 30, 20};  // sorted: 10 20 30 40
  EXPECT_DOUBLE_EQ(Percentile(v, 0.0), 10);
  EXPECT_DOUBLE_EQ(Percentile(v, 1.0), 40);
  EXPECT_DOUBLE_EQ(Percentile(v, 0.5), 25);  // rank 1.5: halfway between 20 and 30
  EXPECT_DOUBLE_EQ(Percentile(v, 0.9), 37);  // rank 2.7: 30 + 0.7 * 10
  std::vector<double> one = {7};
  EXPECT_DOUBLE_EQ(Percentile(one, 0.99), 7);
  std::vector<double> none;
  EXPECT_DOUBLE_EQ(Percentile(none, 0.5), 0);
}

TEST(LoadStatsTest, SummaryOfOneToAHundred) {
  std::vector<double> v;
  for (int i = 100; i >= 1; --i) v.push_back(i);
  const LatencySummary s = Summarize(v);
  EXPECT_DOUBLE_EQ(s.p50, 50.5);  // rank 49.5 of 1..100
  EXPECT_DOUBLE_EQ(s.p90, 90.1);  // rank 89.1
  EXPECT_DOUBLE_EQ(s.p99, 99.01);
  EXPECT_DOUBLE_EQ(s.max, 100);
}

TEST(LoadStatsTest, RatesFromFramesAndSeconds) {
  RunResult r;
  r.vertices = 100'000;
  r.frames = 300;
  r.seconds = 2.0;
  EXPECT_DOUBLE_EQ(r.frames_per_second(), 150);
  EXPECT_DOUBLE_EQ(r.vertices_per_second(), 15e6);
  EXPECT_DOUBLE_EQ(r.megabytes_per_second(), 180);  // 12 bytes per vertex
  r.normals = true;
  EXPECT_DOUBLE_EQ(r.megabytes_per_second(), 360);
  r.server_compute_ms_sum = 600;
  EXPECT_DOUBLE_EQ(r.mean(r.server_compute_ms_sum), 2);
  EXPECT_FALSE(r.failed());
  r.errors["UNAVAILABLE"] = 2;
  r.errors["INTERNAL"] = 1;
  EXPECT_EQ(r.error_count(), 3u);
  EXPECT_TRUE(r.failed());
  RunResult empty;
  EXPECT_DOUBLE_EQ(empty.frames_per_second(), 0);
}

}  // namespace
}  // namespace skinserve::load
