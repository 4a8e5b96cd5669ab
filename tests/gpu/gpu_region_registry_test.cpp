// GpuRegionRegistry alone, with device memory that only counts its life: owners see only
// their own regions; limits refuse before anything is imported; a failed import leaves
// nothing reserved; an unregister answers only after the last frame let go and the import
// was released; idle regions are dropped.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "gpu/gpu_region_registry.h"

namespace skinserve::server {
namespace {

class CountedMemory final : public DeviceMemory {
 public:
  CountedMemory(uint64_t bytes, std::atomic<int>* alive) : bytes_(bytes), alive_(alive) {
    ++*alive_;
  }
  ~CountedMemory() override { --*alive_; }
  uint64_t byte_size() const override { return bytes_; }
  const std::string& backend() const override { return backend_; }

 private:
  uint64_t bytes_;
  std::atomic<int>* alive_;
  std::string backend_ = "opencl";
};

RegionOwner Owner(const std::string& id) { return RegionOwner{.id = id, .file_uid = 1000}; }

struct Importer {
  std::atomic<int> alive{0};
  int calls = 0;
  GpuRegionRegistry::Importer For(uint64_t bytes) {
    return [this, bytes]() -> Result<std::shared_ptr<DeviceMemory>> {
      ++calls;
      return std::shared_ptr<DeviceMemory>(std::make_shared<CountedMemory>(bytes, &alive));
    };
  }
};

TEST(GpuRegionRegistryTest, OwnersSeeOnlyTheirOwn) {
  GpuRegionRegistry registry({});
  Importer import;
  ASSERT_TRUE(registry.Register("a", 1024, Owner("uid 1 pid 2"), import.For(1024)).ok());
  // Another owner may use the same name; it sees, acquires, unregisters nothing of the first's.
  const RegionOwner other = Owner("uid 1 pid 3");
  EXPECT_TRUE(registry.List(other).empty());
  EXPECT_EQ(registry.Acquire("a", other).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(registry.Unregister("a", other, nullptr).code(), StatusCode::kNotFound);
  ASSERT_TRUE(registry.Register("a", 1024, other, import.For(1024)).ok());
  EXPECT_EQ(registry.List(Owner("uid 1 pid 2")).size(), 1u);
  EXPECT_EQ(registry.Register("a", 1024, other, import.For(1024)).status().code(),
            StatusCode::kAlreadyExists);
  EXPECT_EQ(import.calls, 2);
}

TEST(GpuRegionRegistryTest, LimitsRefuseBeforeImporting) {
  GpuRegionRegistry registry({.budget_bytes = 4096, .max_regions = 3, .max_per_owner = 2});
  Importer import;
  const RegionOwner a = Owner("a"), b = Owner("b");
  Result<GpuRegionInfo> over = registry.Register("big", 8192, a, import.For(8192));
  EXPECT_EQ(over.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(over.status().message().find("--gpu-region-budget-mb"), std::string::npos);
  ASSERT_TRUE(registry.Register("1", 1000, a, import.For(1000)).ok());
  ASSERT_TRUE(registry.Register("2", 1000, a, import.For(1000)).ok());
  Result<GpuRegionInfo> third = registry.Register("3", 1000, a, import.For(1000));
  EXPECT_EQ(third.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(third.status().message().find("--shm-max-regions-per-connection = 2"),
            std::string::npos);
  ASSERT_TRUE(registry.Register("1", 1000, b, import.For(1000)).ok());
  Result<GpuRegionInfo> fourth = registry.Register("2", 1000, b, import.For(1000));
  EXPECT_EQ(fourth.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(fourth.status().message().find("--gpu-max-regions = 3"), std::string::npos);
  EXPECT_EQ(import.calls, 3);
  EXPECT_EQ(registry.imported_bytes(), 3000u);
  EXPECT_EQ(registry.Register("bad/name", 1, b, import.For(1)).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(GpuRegionRegistryTest, FailedImportLeavesNothingReserved) {
  GpuRegionRegistry registry({.budget_bytes = 4096});
  const RegionOwner a = Owner("a");
  Result<GpuRegionInfo> failed = registry.Register("x", 4096, a, [] {
    return Result<std::shared_ptr<DeviceMemory>>(FailedPrecondition("lacks cl_khr_x"));
  });
  EXPECT_EQ(failed.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(failed.status().message().find("GPU region 'x': lacks cl_khr_x"), std::string::npos);
  EXPECT_EQ(registry.imported_bytes(), 0u);
  Importer import;
  EXPECT_TRUE(registry.Register("x", 4096, a, import.For(4096)).ok());  // name and bytes free
}

TEST(GpuRegionRegistryTest, UnregisterAnswersAfterTheLastFrameAndTheRelease) {
  GpuRegionRegistry registry({});
  Importer import;
  const RegionOwner a = Owner("a");
  ASSERT_TRUE(registry.Register("r", 64, a, import.For(64)).ok());
  Result<std::shared_ptr<GpuRegion>> frame = registry.Acquire("r", a);  // a frame in flight
  ASSERT_TRUE(frame.ok());
  std::atomic<int> answered{0};
  int alive_at_answer = -1;
  ASSERT_TRUE(registry
                  .Unregister("r", a,
                              [&] {
                                alive_at_answer = import.alive.load();
                                ++answered;
                              })
                  .ok());
  EXPECT_EQ(answered.load(), 0);
  EXPECT_TRUE((*frame)->removed());  // the frame will fail naming it
  EXPECT_EQ(registry.Acquire("r", a).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(registry.imported_bytes(), 0u);  // the budget is free at once
  frame->reset();
  EXPECT_EQ(answered.load(), 1);
  EXPECT_EQ(alive_at_answer, 0);  // released before the answer
}

TEST(GpuRegionRegistryTest, IdleRegionsAreDropped) {
  GpuRegionRegistry registry({.idle_seconds = 0.2});
  Importer import;
  ASSERT_TRUE(registry.Register("r", 64, Owner("a"), import.For(64)).ok());
  for (int i = 0; i < 100 && import.alive.load() > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(import.alive.load(), 0);
  EXPECT_EQ(registry.Acquire("r", Owner("a")).status().code(), StatusCode::kFailedPrecondition);
}

// Device memory with a semaphore that counts its signals, or fails them.
class SignallingMemory final : public DeviceMemory {
 public:
  explicit SignallingMemory(bool fail) : fail_(fail) {}
  uint64_t byte_size() const override { return 1024; }
  const std::string& backend() const override { return backend_; }
  bool signals_semaphore() const override { return true; }
  Status SignalFrameWritten() const override {
    if (fail_) return Internal("clEnqueueSignalSemaphoresKHR failed");
    ++signals;
    return Status::Ok();
  }
  mutable int signals = 0;

 private:
  const bool fail_;
  std::string backend_ = "opencl";
};

TEST(GpuRegionRegistryTest, EachFrameWrittenSignalsTheSemaphoreOnce) {
  GpuRegionRegistry registry({});
  auto memory = std::make_shared<SignallingMemory>(false);
  const RegionOwner owner = Owner("uid 1 pid 2");
  auto info = registry.Register("a", 1024, owner, [&]() -> Result<std::shared_ptr<DeviceMemory>> {
    return std::shared_ptr<DeviceMemory>(memory);
  });
  ASSERT_TRUE(info.ok());
  EXPECT_TRUE(info->signals_semaphore);
  auto region = registry.Acquire("a", owner);
  ASSERT_TRUE(region.ok());
  for (uint64_t frame = 0; frame < 3; ++frame) {
    ASSERT_TRUE((*region)->FrameWritten(frame).ok());
    EXPECT_EQ(memory->signals, static_cast<int>(frame) + 1);
  }
  EXPECT_EQ((*region)->frames(), 3u);
  // Unregistered while a frame held it: the frame fails and nothing is signalled.
  ASSERT_TRUE(registry.Unregister("a", owner, nullptr).ok());
  const Status gone = (*region)->FrameWritten(3);
  EXPECT_EQ(gone.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(gone.message().find("was unregistered while frame 3 was in flight"), std::string::npos);
  EXPECT_EQ(memory->signals, 3);
  EXPECT_EQ((*region)->frames(), 3u);
}

TEST(GpuRegionRegistryTest, AFailedSignalFailsTheFrame) {
  GpuRegionRegistry registry({});
  const RegionOwner owner = Owner("uid 1 pid 2");
  ASSERT_TRUE(registry
                  .Register("a", 1024, owner,
                            []() -> Result<std::shared_ptr<DeviceMemory>> {
                              return std::shared_ptr<DeviceMemory>(
                                  std::make_shared<SignallingMemory>(true));
                            })
                  .ok());
  auto region = registry.Acquire("a", owner);
  ASSERT_TRUE(region.ok());
  const Status failed = (*region)->FrameWritten(7);
  EXPECT_EQ(failed.code(), StatusCode::kInternal);
  EXPECT_NE(failed.message().find("frame 7 is in the buffer, but its semaphore was not signalled"),
            std::string::npos)
      << failed.message();
  EXPECT_EQ((*region)->frames(), 0u);
}

}  // namespace
}  // namespace skinserve::server
