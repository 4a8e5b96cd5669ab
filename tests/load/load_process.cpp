#include "load_process.h"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {
namespace {

std::vector<std::string> ServerArguments(int streams_per_connection,
                                         std::vector<std::string> extra) {
  std::vector<std::string> args = {"--log-level", "warn"};
  args.insert(args.end(), extra.begin(), extra.end());
  if (streams_per_connection > 0) {
    args.insert(args.end(),
                {"--max-streams-per-connection", std::to_string(streams_per_connection)});
  }
  return args;
}

}  // namespace

std::string UniqueJsonPath() {
  static int next = 0;
  return ::testing::TempDir() + "load-" + std::to_string(getpid()) + "-" + std::to_string(next++) +
         ".json";
}

ServerProcess::ServerProcess(int streams_per_connection, std::vector<std::string> extra)
    : child_(ServerArguments(streams_per_connection, std::move(extra))) {
  EXPECT_TRUE(child_.ready()) << child_.error();
}

MeteredServer::MeteredServer()
    : metrics_port_(FreePort()),
      server_(
          0, {"--threads", "1", "--metrics-listen", "127.0.0.1:" + std::to_string(metrics_port_)}) {
}

nlohmann::json MeteredServer::RunLoad(const std::string& args, int* exit_code, std::string* csv,
                                      std::string* json) {
  std::string csv_arg;
  if (csv != nullptr) {
    *csv = UniqueJsonPath() + ".csv";
    csv_arg = " --csv " + *csv;
  }
  return testing::RunLoad("--target " + server_.target() + " " + args + csv_arg +
                              " --metrics-url http://127.0.0.1:" + std::to_string(metrics_port_) +
                              "/metrics",
                          exit_code, json);
}

std::map<std::string, uint64_t> ServerProcess::FramesServed() const {
  client::SkinClient c(client::MakeChannel(target()));
  std::map<std::string, uint64_t> frames;
  auto stats = c.GetServerStats();
  EXPECT_TRUE(stats.ok()) << stats.status().ToString();
  if (stats.ok()) {
    for (const auto& b : stats->backends()) frames[b.id()] = b.frames();
  }
  return frames;
}

std::string RunCommand(const std::string& command, int* exit_code) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  std::string output;
  if (pipe == nullptr) {
    *exit_code = -1;
    return output;
  }
  char buffer[512];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) output += buffer;
  const int status = pclose(pipe);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return output;
}

nlohmann::json RunLoad(const std::string& args, int* exit_code, std::string* json_path,
                       std::string* output) {
  const std::string json = UniqueJsonPath();
  if (json_path != nullptr) *json_path = json;
  const std::string command = std::string(SKINSERVE_LOAD_BINARY) + " " + args + " --json " + json;
  if (output != nullptr) {
    *output = RunCommand(command, exit_code);
  } else {
    const int status = std::system((command + " > /dev/null").c_str());
    *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::ifstream in(json);
  nlohmann::json doc;
  if (in) in >> doc;
  return doc;
}

std::map<std::string, uint64_t> FramesReported(const nlohmann::json& doc) {
  std::map<std::string, uint64_t> frames;
  for (const auto& r : doc["results"]) {
    EXPECT_TRUE(r["errors"].empty()) << r.dump();
    EXPECT_EQ(r["mismatches"], 0) << r.dump();
    frames[r["backend"]] += r["frames"].get<uint64_t>();
  }
  return frames;
}

int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof(address);
  int port = 0;
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), size) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
    port = ntohs(address.sin_port);
  }
  close(fd);
  return port;
}

}  // namespace skinserve::testing
