#include "observability/process_metrics.h"

#include <dirent.h>
#include <fmt/format.h>
#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <vector>

#include "options/cgroup_limits.h"

namespace skinserve::server {
namespace {

// /proc/self/stat's fields after the command name (which may hold spaces and parentheses,
// so it ends at the last ')'): index 0 is field 3 (state) of proc(5).
std::vector<std::string> StatFields() {
  std::ifstream in("/proc/self/stat");
  std::string line;
  std::getline(in, line);
  const auto close = line.rfind(')');
  if (close == std::string::npos) return {};
  std::istringstream rest(line.substr(close + 1));
  return {std::istream_iterator<std::string>(rest), std::istream_iterator<std::string>()};
}

// proc(5) field number (1-based, as the manual counts) of /proc/self/stat, as a number.
std::optional<double> StatField(const std::vector<std::string>& fields, int number) {
  const std::size_t index = static_cast<std::size_t>(number - 3);
  if (index >= fields.size()) return std::nullopt;
  try {
    return std::stod(fields[index]);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// The boot time, seconds since the epoch (/proc/stat's btime).
std::optional<double> BootTime() {
  std::ifstream in("/proc/stat");
  std::string key;
  double value = 0;
  while (in >> key) {
    if (key == "btime" && in >> value) return value;
    in.ignore(1 << 16, '\n');
  }
  return std::nullopt;
}

// Open descriptors: the entries of /proc/self/fd, less the one reading the folder takes.
std::optional<double> OpenFds() {
  DIR* dir = opendir("/proc/self/fd");
  if (dir == nullptr) return std::nullopt;
  double n = 0;
  while (const dirent* entry = readdir(dir)) {
    if (entry->d_name[0] != '.') ++n;
  }
  closedir(dir);
  return n - 1;
}

void Gauge(std::string& out, const char* name, const char* type, const char* help,
           std::optional<double> value) {
  fmt::format_to(std::back_inserter(out), "# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  if (value) fmt::format_to(std::back_inserter(out), "{} {}\n", name, *value);
}

}  // namespace

std::string RenderProcessMetrics() {
  const auto fields = StatFields();
  const double ticks = static_cast<double>(sysconf(_SC_CLK_TCK));
  const double page = static_cast<double>(sysconf(_SC_PAGESIZE));
  std::optional<double> cpu, start, rss, vsize;
  if (auto user = StatField(fields, 14), kernel = StatField(fields, 15); user && kernel) {
    cpu = (*user + *kernel) / ticks;
  }
  if (auto since_boot = StatField(fields, 22), boot = BootTime(); since_boot && boot) {
    start = *boot + *since_boot / ticks;
  }
  if (auto pages = StatField(fields, 24)) rss = *pages * page;
  vsize = StatField(fields, 23);
  std::optional<double> max_fds;
  if (rlimit limit{}; getrlimit(RLIMIT_NOFILE, &limit) == 0) {
    max_fds = limit.rlim_cur == RLIM_INFINITY ? -1.0 : static_cast<double>(limit.rlim_cur);
  }
  const CgroupLimits cgroup = ReadCgroupLimits();
  // Every thread's, those that ended too (a frame-socket connection's thread ends with it):
  // /proc/self/task/*/status would lose theirs.
  rusage usage = {};
  const bool have_usage = getrusage(RUSAGE_SELF, &usage) == 0;

  std::string out;
  Gauge(out, "process_cpu_seconds_total", "counter",
        "Total user and system CPU time spent in seconds.", cpu);
  Gauge(out, "process_resident_memory_bytes", "gauge", "Resident memory size in bytes.", rss);
  Gauge(out, "process_virtual_memory_bytes", "gauge", "Virtual memory size in bytes.", vsize);
  Gauge(out, "process_open_fds", "gauge", "Number of open file descriptors.", OpenFds());
  Gauge(out, "process_max_fds", "gauge", "Maximum number of open file descriptors.", max_fds);
  Gauge(out, "process_start_time_seconds", "gauge",
        "Start time of the process since unix epoch in seconds.", start);
  fmt::format_to(std::back_inserter(out),
                 "# HELP skinserve_process_context_switches_total Context switches of all the "
                 "process's threads, ended ones included (getrusage): voluntary (a thread "
                 "blocked) and involuntary (preempted).\n"
                 "# TYPE skinserve_process_context_switches_total counter\n");
  if (have_usage) {
    fmt::format_to(std::back_inserter(out),
                   "skinserve_process_context_switches_total{{kind=\"voluntary\"}} {}\n"
                   "skinserve_process_context_switches_total{{kind=\"involuntary\"}} {}\n",
                   usage.ru_nvcsw, usage.ru_nivcsw);
  }
  Gauge(out, "skinserve_memory_limit_bytes", "gauge",
        "The cgroup memory limit the process runs under (memory.max); 0: no limit.",
        static_cast<double>(cgroup.memory_bytes.value_or(0)));
  return out;
}

}  // namespace skinserve::server
