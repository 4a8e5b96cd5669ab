#include "compute_pool.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

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

// A flexible task (a parallel backend's frame) that records the threads it was granted.
struct Grants {
  std::mutex mutex;
  std::vector<std::pair<int, int>> granted;  // (tag, threads) in start order
  std::atomic<int> finished{0};
};

struct Tagged {
  Grants* grants;
  int tag;
};

ComputePool::Task Flexible(Tagged* tagged, int max_width, uint64_t work, uint32_t parts = 1) {
  ComputePool::Task task;
  task.run = [](void* context, uint32_t, int threads) {
    auto* t = static_cast<Tagged*>(context);
    {
      std::lock_guard lock(t->grants->mutex);
      t->grants->granted.emplace_back(t->tag, threads);
    }
    t->grants->finished.fetch_add(1);
  };
  task.context = tagged;
  task.parts = parts;
  task.min_width = 1;
  task.max_width = max_width;
  task.work = work;
  return task;
}

// Holds `count` pool threads until released, so the test decides what waits.
struct Blocker {
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> started{0};
  void Occupy(ComputePool& pool, int count) {
    for (int i = 0; i < count; ++i) {
      ASSERT_TRUE(pool.TrySubmit(1, [this] {
        started.fetch_add(1);
        released.wait();
      }));
    }
    while (started.load() < count) std::this_thread::yield();
  }
};

TEST(ComputePoolTest, WaitingFramesRunSideBySideOneThreadEach) {
  Grants grants;
  std::vector<Tagged> tags = {{&grants, 0}, {&grants, 1}, {&grants, 2}};
  ComputePool pool(4, 16, /*split_min_work=*/1000);
  Blocker blocker;
  blocker.Occupy(pool, 4);
  // Three large frames of a 4-thread backend wait together: none is split while others wait.
  for (auto& tag : tags) ASSERT_TRUE(pool.TrySubmit(Flexible(&tag, 4, 1'000'000)));
  blocker.release.set_value();
  pool.Shutdown();
  ASSERT_EQ(grants.granted.size(), 3u);
  // Frames that start together record their grants in any order: compare them by frame.
  std::sort(grants.granted.begin(), grants.granted.end());
  EXPECT_EQ(grants.granted[0], std::make_pair(0, 1)) << "frame 1 waited behind it";
  EXPECT_EQ(grants.granted[1], std::make_pair(1, 1)) << "frame 2 waited behind it";
  EXPECT_EQ(grants.granted[2].first, 2);  // the last may take the threads left idle
  EXPECT_LE(pool.peak_busy(), 4);
}

TEST(ComputePoolTest, ALoneFrameIsSplitOnlyWhenLargeEnough) {
  Grants grants;
  Tagged large{&grants, 0}, small{&grants, 1}, medium{&grants, 2};
  ComputePool pool(4, 16, /*split_min_work=*/1000);
  ASSERT_TRUE(pool.TrySubmit(Flexible(&large, 4, 1'000'000)));
  while (grants.finished.load() < 1) std::this_thread::yield();
  ASSERT_TRUE(pool.TrySubmit(Flexible(&small, 4, 999)));  // not worth waking a team
  while (grants.finished.load() < 2) std::this_thread::yield();
  ASSERT_TRUE(pool.TrySubmit(Flexible(&medium, 4, 2500)));  // worth two threads
  pool.Shutdown();
  ASSERT_EQ(grants.granted.size(), 3u);
  EXPECT_EQ(grants.granted[0], std::make_pair(0, 3)) << "one thread stays free for arrivals";
  EXPECT_EQ(grants.granted[1], std::make_pair(1, 1));
  EXPECT_EQ(grants.granted[2], std::make_pair(2, 2));
}

TEST(ComputePoolTest, ACrowdsPartsRunSideBySide) {
  std::atomic<int> busy{0}, peak{0};
  struct Context {
    std::atomic<int>* busy;
    std::atomic<int>* peak;
    std::atomic<int> parts{0};
    std::promise<void> all;
  } context{&busy, &peak};
  ComputePool::Task task;
  task.run = [](void* c, uint32_t, int threads) {
    auto* ctx = static_cast<Context*>(c);
    EXPECT_EQ(threads, 1);
    const int now = ctx->busy->fetch_add(1) + 1;
    int seen = ctx->peak->load();
    while (now > seen && !ctx->peak->compare_exchange_weak(seen, now)) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ctx->busy->fetch_sub(1);
    if (ctx->parts.fetch_add(1) + 1 == 6) ctx->all.set_value();
  };
  task.context = &context;
  task.parts = 6;
  task.max_width = 2;
  task.work = 1'000'000;
  ComputePool pool(2, 1, 1000);
  ASSERT_TRUE(pool.TrySubmit(task));  // six parts take one queue slot
  EXPECT_EQ(context.all.get_future().wait_for(std::chrono::seconds(30)), std::future_status::ready);
  pool.Shutdown();
  EXPECT_EQ(context.parts.load(), 6);
  EXPECT_EQ(peak.load(), 2) << "the parts ran side by side";
  EXPECT_LE(pool.peak_busy(), 2);
}

TEST(ComputePoolTest, AFixedWidthTaskWaitsForItsThreadsAndKeepsItsTurn) {
  ComputePool pool(2, 16);
  Blocker blocker;
  blocker.Occupy(pool, 1);  // one of two threads busy
  std::mutex mutex;
  std::vector<int> order;
  auto record = [&](int tag) {
    return [&, tag] {
      std::lock_guard lock(mutex);
      order.push_back(tag);
    };
  };
  ASSERT_TRUE(pool.TrySubmit(2, record(0)));  // needs both: waits at the head
  ASSERT_TRUE(pool.TrySubmit(1, record(1)));  // could run now, but arrived later
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    std::lock_guard lock(mutex);
    EXPECT_TRUE(order.empty()) << "nothing overtakes the wide task at the head";
  }
  blocker.release.set_value();
  pool.Shutdown();
  EXPECT_EQ(order, (std::vector<int>{0, 1}));
}

// TryRunInline: a small single frame runs on the caller's thread when a pool thread is free
// and nothing waits; anything else is left to TrySubmit (the pool's threads).
TEST(ComputePoolTest, ASmallLoneFrameRunsOnItsCallersThread) {
  struct Where {
    std::thread::id id;
    int threads = 0;
  } where;
  ComputePool::Task task;
  task.run = [](void* context, uint32_t, int threads) {
    auto* w = static_cast<Where*>(context);
    w->id = std::this_thread::get_id();
    w->threads = threads;
  };
  task.context = &where;
  task.max_width = 4;
  task.work = 999;
  ComputePool pool(2, 16, /*split_min_work=*/1000);
  ASSERT_TRUE(pool.TryRunInline(task));
  EXPECT_EQ(where.id, std::this_thread::get_id());
  EXPECT_EQ(where.threads, 1);
  EXPECT_EQ(pool.inline_runs(), 1u);
}

TEST(ComputePoolTest, FramesThatBuyParallelismAreNotRunInline) {
  std::atomic<int> ran{0};
  ComputePool::Task task;
  task.run = [](void* context, uint32_t, int) {
    static_cast<std::atomic<int>*>(context)->fetch_add(1);
  };
  task.context = &ran;
  ComputePool pool(2, 16, /*split_min_work=*/1000);
  ComputePool::Task large = task;
  large.work = 1000;  // worth splitting: the pool decides its width
  EXPECT_FALSE(pool.TryRunInline(large));
  ComputePool::Task crowd = task;
  crowd.parts = 2;  // its instances run side by side on the pool
  EXPECT_FALSE(pool.TryRunInline(crowd));
  ComputePool::Task fixed = task;
  fixed.min_width = fixed.max_width = 2;  // needs a team
  EXPECT_FALSE(pool.TryRunInline(fixed));
  EXPECT_EQ(ran.load(), 0);
  EXPECT_EQ(pool.inline_runs(), 0u);
}

TEST(ComputePoolTest, NothingRunsInlineWhileFramesWaitOrEveryThreadIsBusy) {
  std::atomic<int> ran{0};
  ComputePool::Task small;
  small.run = [](void* context, uint32_t, int) {
    static_cast<std::atomic<int>*>(context)->fetch_add(1);
  };
  small.context = &ran;
  small.work = 1;
  ComputePool pool(1, 16, /*split_min_work=*/1000);
  Blocker blocker;
  blocker.Occupy(pool, 1);  // the only thread is busy
  EXPECT_FALSE(pool.TryRunInline(small)) << "it would skin beside the pool's thread: > size()";
  ASSERT_TRUE(pool.TrySubmit(small));  // waits for the thread
  EXPECT_FALSE(pool.TryRunInline(small)) << "it would overtake the frame queued before it";
  blocker.release.set_value();
  pool.Shutdown();
  EXPECT_EQ(ran.load(), 1);
  EXPECT_EQ(pool.inline_runs(), 0u);
  EXPECT_FALSE(pool.TryRunInline(small)) << "shut down";
}

// While a frame runs inline it holds one of the pool's threads: the pool's own threads
// never skin more frames than it has threads beside it.
TEST(ComputePoolTest, AnInlineFrameTakesAThreadsPlace) {
  Occupancy occupancy;
  ComputePool pool(1, 16, /*split_min_work=*/1000);
  struct Context {
    Occupancy* occupancy;
    std::promise<void>* inside;
    std::shared_future<void> release;
  };
  std::promise<void> inside, release;
  Context context{&occupancy, &inside, release.get_future().share()};
  ComputePool::Task held;
  held.run = [](void* c, uint32_t, int) {
    auto* ctx = static_cast<Context*>(c);
    ctx->occupancy->Enter(1);
    ctx->inside->set_value();
    ctx->release.wait();
    ctx->occupancy->Leave(1);
  };
  held.context = &context;
  held.work = 1;
  std::thread caller([&] { EXPECT_TRUE(pool.TryRunInline(held)); });
  inside.get_future().wait();
  std::atomic<int> ran{0};
  ASSERT_TRUE(pool.TrySubmit(1, [&] {
    occupancy.Enter(1);
    occupancy.Leave(1);
    ran.fetch_add(1);
  }));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(ran.load(), 0) << "the queued frame ran beside the inline one on a 1-thread pool";
  release.set_value();
  caller.join();
  pool.Shutdown();
  EXPECT_EQ(ran.load(), 1);
  EXPECT_LE(occupancy.peak.load(), 1);
  EXPECT_EQ(pool.peak_busy(), 1);
}

}  // namespace
}  // namespace skinserve
