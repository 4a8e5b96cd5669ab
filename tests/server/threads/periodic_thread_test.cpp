// PeriodicThread on its own: it ticks again and again, no tick runs after Stop, Stop wakes a
// thread whose period is far away, and a second Stop (or the destructor after one) does
// nothing.
#include "threads/periodic_thread.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace skinserve::testing {
namespace {

using server::PeriodicThread;
using namespace std::chrono_literals;

// Waits (up to a minute, so a slow machine does not fail it) until `count` reaches `at_least`.
bool WaitFor(const std::atomic<int>& count, int at_least) {
  const auto give_up = std::chrono::steady_clock::now() + 60s;
  while (count.load() < at_least) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

TEST(PeriodicThreadTest, TicksEveryPeriodUntilStopped) {
  std::atomic<int> ticks{0};
  PeriodicThread thread(1ms, [&] { ++ticks; });
  ASSERT_TRUE(WaitFor(ticks, 3)) << "ticks: " << ticks.load();
  thread.Stop();
  const int at_stop = ticks.load();
  std::this_thread::sleep_for(20ms);  // twenty periods
  EXPECT_EQ(ticks.load(), at_stop) << "a tick ran after Stop returned";
}

TEST(PeriodicThreadTest, StopWakesAThreadWhosePeriodIsAnHourAway) {
  std::atomic<int> ticks{0};
  PeriodicThread thread(std::chrono::hours(1), [&] { ++ticks; });
  thread.Stop();  // returns now, not in an hour (ctest's timeout would end the test)
  EXPECT_EQ(ticks.load(), 0);
}

TEST(PeriodicThreadTest, StopLetsATickInProgressFinish) {
  std::atomic<int> started{0}, finished{0};
  PeriodicThread thread(1ms, [&] {
    ++started;
    std::this_thread::sleep_for(20ms);
    ++finished;
  });
  ASSERT_TRUE(WaitFor(started, 1));
  thread.Stop();
  EXPECT_EQ(started.load(), finished.load()) << "Stop returned during a tick";
}

TEST(PeriodicThreadTest, SecondStopAndDestructorAfterStopDoNothing) {
  std::atomic<int> ticks{0};
  {
    PeriodicThread thread(1ms, [&] { ++ticks; });
    ASSERT_TRUE(WaitFor(ticks, 1));
    thread.Stop();
    thread.Stop();
  }
  SUCCEED();
}

}  // namespace
}  // namespace skinserve::testing
