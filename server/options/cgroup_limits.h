// What the container's cgroup allows this process: its memory limit and its CPU quota, as a
// process inside a container sees them at the root of /sys/fs/cgroup (cgroup v2: memory.max,
// cpu.max; cgroup v1: memory/memory.limit_in_bytes, cpu/cpu.cfs_quota_us and
// cpu.cfs_period_us). A process that sees every core of the node and all its memory would
// otherwise size its threads and budgets for the node, not for its quota.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace skinserve::server {

struct CgroupLimits {
  std::optional<uint64_t> memory_bytes;  // none: unlimited or unreadable
  std::optional<double> cpus;            // quota / period, e.g. 1.5; none: unlimited
  // The CPU quota in whole cores, rounded up (a quota of 1.5 runs on 2 cores part-time).
  std::optional<int> whole_cpus() const;
};

// Reads the limits under `root` (the cgroup file system's mount point).
CgroupLimits ReadCgroupLimits(const std::string& root = "/sys/fs/cgroup");

}  // namespace skinserve::server
