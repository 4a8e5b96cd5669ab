#include "compute_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>

namespace skinserve {
namespace {

// Counts the threads inside tasks, as a task of `width` would occupy them.
struct Occupancy {
  std::atomic<int> busy{0};
  std::atomic<int> peak{0};
  void Enter(int width) {
    const int now = busy.fetch_add(width) + width;
    int seen = peak.load();
    while (now > seen && !peak.compare_exchange_weak(seen, now)) {
    }
  }
  void Leave(int width) { busy.fetch_sub(width); }
};

TEST(ComputePoolTest, NeverOccupiesMoreThreadsThanItHas) {
  Occupancy occupancy;
  std::atomic<int> ran{0};
  {
    ComputePool pool(2, 1000);
    for (int i = 0; i < 60; ++i) {
      const int width = (i % 3 == 0) ? 2 : 1;
      ASSERT_TRUE(pool.TrySubmit(width, [&, width] {
        occupancy.Enter(width);
        std::this_thread::sleep_for(std::chrono::microseconds(300));
        occupancy.Leave(width);
        ran.fetch_add(1);
      }));
    }
    pool.Shutdown();
  }
  EXPECT_EQ(ran.load(), 60);
  EXPECT_LE(occupancy.peak.load(), 2);
}

TEST(ComputePoolTest, RefusesWorkWhenTheQueueIsFull) {
  ComputePool pool(1, 2);
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> started;
  ASSERT_TRUE(pool.TrySubmit(1, [&] {
    started.set_value();
    released.wait();
  }));
  started.get_future().wait();  // the first task holds the only thread, not a queue slot
  EXPECT_TRUE(pool.TrySubmit(1, [] {}));
  EXPECT_TRUE(pool.TrySubmit(1, [] {}));
  EXPECT_EQ(pool.depth(), 2u);
  EXPECT_FALSE(pool.TrySubmit(1, [] {}));
  release.set_value();
  pool.Shutdown();
  EXPECT_EQ(pool.depth(), 0u);
}

TEST(ComputePoolTest, ShutdownRunsWhatWasQueuedThenRefuses) {
  std::atomic<int> ran{0};
  ComputePool pool(1, 100);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(pool.TrySubmit(1, [&] {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      ran.fetch_add(1);
    }));
  }
  pool.Shutdown();
  EXPECT_EQ(ran.load(), 20);
  EXPECT_FALSE(pool.TrySubmit(1, [] {}));
  pool.Shutdown();  // idempotent
}

TEST(ComputePoolTest, WideTasksClampToThePoolSize) {
  ComputePool pool(2, 10);
  std::promise<void> done;
  ASSERT_TRUE(pool.TrySubmit(64, [&] { done.set_value(); }));
  EXPECT_EQ(done.get_future().wait_for(std::chrono::seconds(10)), std::future_status::ready);
}

}  // namespace
}  // namespace skinserve
