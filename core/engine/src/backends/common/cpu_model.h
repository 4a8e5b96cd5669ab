// The CPU's model name, for BackendInfo::device.
#pragma once

#include <fstream>
#include <string>

namespace skinserve {

inline std::string CpuModelName() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos && colon + 2 <= line.size()) return line.substr(colon + 2);
    }
  }
  return "x86-64 CPU";
}

}  // namespace skinserve
