#include "options/cgroup_limits.h"

#include <cmath>
#include <fstream>

namespace skinserve::server {
namespace {

// cgroup v1 writes "unlimited" as the largest page-aligned 64-bit value; anything this large
// is no limit.
constexpr uint64_t kUnlimitedBytes = uint64_t{1} << 62;

std::optional<std::string> ReadWord(const std::string& path, int index = 0) {
  std::ifstream in(path);
  std::string word;
  for (int i = 0; i <= index; ++i) {
    if (!(in >> word)) return std::nullopt;
  }
  return word;
}

std::optional<double> ReadNumber(const std::string& path, int index = 0) {
  const auto word = ReadWord(path, index);
  if (!word || *word == "max") return std::nullopt;
  try {
    std::size_t used = 0;
    const double value = std::stod(*word, &used);
    if (used != word->size() || !std::isfinite(value)) return std::nullopt;
    return value;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<uint64_t> MemoryBytes(const std::string& path) {
  const auto value = ReadNumber(path);
  if (!value || *value <= 0 || *value >= static_cast<double>(kUnlimitedBytes)) return std::nullopt;
  return static_cast<uint64_t>(*value);
}

// A quota over a period; a negative quota (v1's -1) or "max" (v2) is none.
std::optional<double> Cpus(std::optional<double> quota, std::optional<double> period) {
  if (!quota || !period || *quota <= 0 || *period <= 0) return std::nullopt;
  return *quota / *period;
}

}  // namespace

std::optional<int> CgroupLimits::whole_cpus() const {
  if (!cpus) return std::nullopt;
  // A hair of slack, so that 200000/100000 read back as 2.0000001 stays 2.
  return std::max(1, static_cast<int>(std::ceil(*cpus - 1e-6)));
}

CgroupLimits ReadCgroupLimits(const std::string& root) {
  CgroupLimits limits;
  // cgroup v2: one hierarchy; "cpu.max" is "QUOTA PERIOD" or "max PERIOD".
  if (std::ifstream(root + "/cgroup.controllers").good()) {
    limits.memory_bytes = MemoryBytes(root + "/memory.max");
    limits.cpus = Cpus(ReadNumber(root + "/cpu.max", 0), ReadNumber(root + "/cpu.max", 1));
    return limits;
  }
  // cgroup v1: one hierarchy per controller ("cpu,cpuacct" is often linked as "cpu").
  limits.memory_bytes = MemoryBytes(root + "/memory/memory.limit_in_bytes");
  limits.cpus =
      Cpus(ReadNumber(root + "/cpu/cpu.cfs_quota_us"), ReadNumber(root + "/cpu/cpu.cfs_period_us"));
  return limits;
}

}  // namespace skinserve::server
