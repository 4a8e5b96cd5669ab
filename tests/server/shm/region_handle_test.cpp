// RegionHandle: a stream's frames into one region look it up once (by owner and name,
// fstat, the SIGBUS guard put back) and after that only check, frame by frame, that it
// still stands: an unregister, a truncation caught by the guard, another name, another
// owner all end the cached hold with the status a fresh lookup would give.
#include "shm/region_handle.h"

#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace skinserve::testing {
namespace {

using server::RegionCaller;
using server::RegionHandle;
using server::RegionLimits;
using server::RegionOwner;
using server::RegionRegistry;

constexpr uint64_t kBytes = 1 << 16;

class RegionHandleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/dev/shm/skinserve-handle-XXXXXX";
    ASSERT_NE(mkdtemp(name), nullptr);
    dir_ = name;
    auto registry = RegionRegistry::Create({.dir = dir_, .budget_bytes = 16 * kBytes});
    ASSERT_TRUE(registry.ok()) << registry.status().ToString();
    registry_ = std::move(registry).value();
    caller_.regions = registry_.get();
    caller_.owner = owner_;
  }
  void TearDown() override {
    registry_.reset();
    std::filesystem::remove_all(dir_);
  }
  // Creates a file of kBytes in the directory and registers it for the owner as `name`.
  void Register(const std::string& name) {
    const std::string path = dir_ + "/" + name + ".bin";
    const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(ftruncate(fd, kBytes), 0);
    close(fd);
    ASSERT_TRUE(registry_->Register(name, name + ".bin", kBytes, owner_).ok());
  }

  std::string dir_;
  std::unique_ptr<RegionRegistry> registry_;
  RegionOwner owner_{.id = "uid test pid 1", .file_uid = getuid()};
  RegionCaller caller_;
};

TEST_F(RegionHandleTest, FramesOfAStreamLookTheirRegionUpOnce) {
  Register("a");
  RegionHandle handle;
  for (int frame = 0; frame < 5; ++frame) {
    auto region = handle.Resolve("a", caller_);
    ASSERT_TRUE(region.ok()) << region.status().ToString();
    EXPECT_EQ((*region)->name(), "a");
  }
  EXPECT_EQ(handle.lookups(), 1u);
}

TEST_F(RegionHandleTest, AnotherNameIsLookedUpAndTheFirstAgainToo) {
  Register("a");
  Register("b");
  RegionHandle handle;
  EXPECT_EQ((*handle.Resolve("a", caller_))->name(), "a");
  EXPECT_EQ((*handle.Resolve("b", caller_))->name(), "b");
  EXPECT_EQ((*handle.Resolve("b", caller_))->name(), "b");
  EXPECT_EQ((*handle.Resolve("a", caller_))->name(), "a");
  EXPECT_EQ(handle.lookups(), 3u);
}

TEST_F(RegionHandleTest, AnUnregisteredRegionFailsTheNextFrameAsALookupWould) {
  Register("a");
  RegionHandle handle;
  ASSERT_TRUE(handle.Resolve("a", caller_).ok());
  bool unmapped = false;
  ASSERT_TRUE(registry_->Unregister("a", owner_, [&] { unmapped = true; }).ok());
  EXPECT_TRUE(unmapped) << "the handle held the region between frames: the unregister waited";
  auto again = handle.Resolve("a", caller_);
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(again.status().message().find("no region named 'a'"), std::string::npos)
      << again.status().message();
  // Registered again under the same name: a new region, found again.
  Register("a");
  EXPECT_TRUE(handle.Resolve("a", caller_).ok());
}

TEST_F(RegionHandleTest, AnotherCallerDoesNotGetTheCachedRegion) {
  Register("a");
  RegionHandle handle;
  ASSERT_TRUE(handle.Resolve("a", caller_).ok());
  RegionCaller stranger;
  stranger.regions = registry_.get();
  stranger.owner = RegionOwner{.id = "uid test pid 2", .file_uid = getuid()};
  auto theirs = handle.Resolve("a", stranger);
  ASSERT_FALSE(theirs.ok()) << "a handle answered for another owner";
  EXPECT_EQ(theirs.status().code(), StatusCode::kFailedPrecondition);
  RegionCaller none;  // shared memory off
  EXPECT_EQ(handle.Resolve("a", none).status().code(), StatusCode::kFailedPrecondition);
}

TEST_F(RegionHandleTest, ATruncationIsFoundWhenResolvedAndTheGuardsMarkAfter) {
  Register("a");
  ASSERT_EQ(truncate((dir_ + "/a.bin").c_str(), 0), 0);
  RegionHandle handle;
  auto region = handle.Resolve("a", caller_);  // looked up: the file is checked
  ASSERT_FALSE(region.ok());
  EXPECT_NE(region.status().message().find("now holds 0 bytes"), std::string::npos)
      << region.status().message();
}

}  // namespace
}  // namespace skinserve::testing
