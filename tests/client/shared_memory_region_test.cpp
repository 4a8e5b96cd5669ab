// SharedMemoryRegion on its own: a region's file is created at its size with its blocks
// allocated (not sparse), zeroed; it is removed with the region; keys
// that are not one file name, and keys in use, are refused naming them.
#include "skinserve/client/shared_memory_region.h"

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace skinserve::client {
namespace {

constexpr uint64_t kBytes = 1 << 20;

TEST(SharedMemoryRegionTest, ARegionsFileIsAllocatedAndZeroed) {
  auto region = SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("region-test"), kBytes);
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  const std::string path = "/dev/shm/" + (*region)->key();
  struct stat st = {};
  ASSERT_EQ(stat(path.c_str(), &st), 0) << std::strerror(errno);
  EXPECT_EQ(static_cast<uint64_t>(st.st_size), kBytes);
  // st_blocks counts 512-byte blocks: a sparse file (ftruncate alone) would have none.
  EXPECT_GE(static_cast<uint64_t>(st.st_blocks) * 512, kBytes) << "the file is sparse";
  const std::span<std::byte> bytes = (*region)->bytes();
  EXPECT_TRUE(
      std::all_of(bytes.begin(), bytes.end(), [](std::byte b) { return b == std::byte{0}; }));
  region->reset();
  EXPECT_NE(access(path.c_str(), F_OK), 0) << path << " outlived its region";
}

TEST(SharedMemoryRegionTest, KeysThatAreNotOneFileNameOrAreInUseAreRefusedNamingThem) {
  for (const char* key : {"a/b", "..", "", "/"}) {
    auto region = SharedMemoryRegion::Create(key, kBytes);
    ASSERT_FALSE(region.ok()) << key;
    EXPECT_EQ(region.status().code(), StatusCode::kInvalidArgument) << key;
  }
  const std::string key = SharedMemoryRegion::UniqueKey("region-test");
  auto first = SharedMemoryRegion::Create(key, kBytes);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  auto second = SharedMemoryRegion::Create(key, kBytes);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kAlreadyExists);
  EXPECT_NE(second.status().message().find(key), std::string::npos) << second.status().message();
  auto elsewhere = SharedMemoryRegion::Create(key, kBytes, "/no/such/folder");
  ASSERT_FALSE(elsewhere.ok());
  EXPECT_EQ(elsewhere.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(elsewhere.status().message().find("/no/such/folder"), std::string::npos)
      << elsewhere.status().message();
}

}  // namespace
}  // namespace skinserve::client
