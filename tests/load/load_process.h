// What the load client's integration tests share: a server child process with the load
// client's view of it, and runs of the skinserve-load (and skinserve-cli) binaries with their
// reports read back.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server_child.h"

namespace skinserve::testing {

// A report file no other run of this test binary writes.
std::string UniqueJsonPath();

// A skinserve child process on a loopback port, with the load client's view of it.
class ServerProcess {
 public:
  // `streams_per_connection`: the server's --max-streams-per-connection (0: its default).
  explicit ServerProcess(int streams_per_connection = 0, std::vector<std::string> extra = {});
  const std::string& target() const { return child_.target(); }
  bool ready() const { return child_.ready(); }
  pid_t pid() const { return child_.pid(); }
  // Frames served per backend, from the server's own stats.
  std::map<std::string, uint64_t> FramesServed() const;

 private:
  ServerChild child_;
};

// A server on one compute thread with its metrics on a loopback port: a load run against it
// (RunLoad here) scrapes them for the server CPU columns and writes a CSV beside its report.
class MeteredServer {
 public:
  MeteredServer();
  ServerProcess& server() { return server_; }
  // Runs skinserve-load with `args` against the server; `csv` (no CSV when null) and `json`
  // (may be null) are told where its CSV and its report went.
  nlohmann::json RunLoad(const std::string& args, int* exit_code, std::string* csv,
                         std::string* json);

 private:
  int metrics_port_;
  ServerProcess server_;
};

// Runs skinserve-load with `args` and returns its --json report (empty when none was
// written); `json_path`, when given, is told where the report went, and `output`, when
// given, receives its standard output (else discarded).
nlohmann::json RunLoad(const std::string& args, int* exit_code, std::string* json_path = nullptr,
                       std::string* output = nullptr);

// Runs `command` through the shell; its standard output and error together, and its exit code.
std::string RunCommand(const std::string& command, int* exit_code);

// Frames per backend over the report's rows, failing the test on any row with errors or
// mismatches.
std::map<std::string, uint64_t> FramesReported(const nlohmann::json& doc);

// A loopback port free a moment ago, for the server's --metrics-listen (it has no port file
// for metrics; tests/ops/metrics-test.sh does the same).
int FreePort();

}  // namespace skinserve::testing
