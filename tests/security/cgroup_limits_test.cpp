// ReadCgroupLimits on cgroup file systems laid out as a container sees them (v2 and v1),
// written into a temporary folder.
#include "options/cgroup_limits.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "security_fixture.h"

namespace skinserve::testing {
namespace {

void Write(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path) << text << "\n";
}

TEST(CgroupLimitsTest, V2QuotaAndMemory) {
  const std::string root = TemporaryFolder("cgroup-v2");
  Write(root + "/cgroup.controllers", "cpuset cpu io memory pids");
  Write(root + "/cpu.max", "150000 100000");
  Write(root + "/memory.max", "3221225472");
  const server::CgroupLimits limits = server::ReadCgroupLimits(root);
  ASSERT_TRUE(limits.cpus.has_value());
  EXPECT_DOUBLE_EQ(*limits.cpus, 1.5);
  EXPECT_EQ(limits.whole_cpus(), 2);  // a quota of 1.5 cores runs on 2, part of the time
  EXPECT_EQ(limits.memory_bytes, 3221225472u);

  Write(root + "/cpu.max", "200000 100000");
  EXPECT_EQ(server::ReadCgroupLimits(root).whole_cpus(), 2);
  Write(root + "/cpu.max", "50000 100000");
  EXPECT_EQ(server::ReadCgroupLimits(root).whole_cpus(), 1);
}

TEST(CgroupLimitsTest, V2Unlimited) {
  const std::string root = TemporaryFolder("cgroup-v2-max");
  Write(root + "/cgroup.controllers", "cpu memory");
  Write(root + "/cpu.max", "max 100000");
  Write(root + "/memory.max", "max");
  const server::CgroupLimits limits = server::ReadCgroupLimits(root);
  EXPECT_FALSE(limits.cpus.has_value());
  EXPECT_FALSE(limits.whole_cpus().has_value());
  EXPECT_FALSE(limits.memory_bytes.has_value());
}

TEST(CgroupLimitsTest, V1QuotaAndMemory) {
  const std::string root = TemporaryFolder("cgroup-v1");
  Write(root + "/cpu/cpu.cfs_quota_us", "300000");
  Write(root + "/cpu/cpu.cfs_period_us", "100000");
  Write(root + "/memory/memory.limit_in_bytes", "1073741824");
  const server::CgroupLimits limits = server::ReadCgroupLimits(root);
  EXPECT_EQ(limits.whole_cpus(), 3);
  EXPECT_EQ(limits.memory_bytes, 1073741824u);
  // v1 writes "no limit" as -1 and as the largest page-aligned 64-bit number.
  Write(root + "/cpu/cpu.cfs_quota_us", "-1");
  Write(root + "/memory/memory.limit_in_bytes", "9223372036854771712");
  const server::CgroupLimits none = server::ReadCgroupLimits(root);
  EXPECT_FALSE(none.cpus.has_value());
  EXPECT_FALSE(none.memory_bytes.has_value());
}

TEST(CgroupLimitsTest, NothingThereIsNoLimit) {
  const server::CgroupLimits limits = server::ReadCgroupLimits(TemporaryFolder("cgroup-none"));
  EXPECT_FALSE(limits.cpus.has_value());
  EXPECT_FALSE(limits.memory_bytes.has_value());
  const std::string garbage = TemporaryFolder("cgroup-garbage");
  Write(garbage + "/cpu/cpu.cfs_quota_us", "lots");
  Write(garbage + "/cpu/cpu.cfs_period_us", "100000");
  Write(garbage + "/memory/memory.limit_in_bytes", "12abc");
  const server::CgroupLimits unreadable = server::ReadCgroupLimits(garbage);
  EXPECT_FALSE(unreadable.cpus.has_value());
  EXPECT_FALSE(unreadable.memory_bytes.has_value());
}

}  // namespace
}  // namespace skinserve::testing
