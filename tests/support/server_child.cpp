#include "server_child.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <thread>

#include "skinserve/client/channel.h"

namespace skinserve::testing {

namespace {

std::string UniquePortFile() {
  static std::atomic<int> counter{0};
  return ::testing::TempDir() + "skinserve-port-" + std::to_string(getpid()) + "-" +
         std::to_string(counter.fetch_add(1));
}

// The port the server wrote, or 0 while the file is not there yet.
int ReadPort(const std::string& path) {
  std::ifstream in(path);
  int port = 0;
  if (!(in >> port)) return 0;
  return port;
}

std::string DescribeExit(int status) {
  if (WIFEXITED(status))
    return "skinserve exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status))
    return "skinserve was killed by signal " + std::to_string(WTERMSIG(status));
  return "skinserve stopped (wait status " + std::to_string(status) + ")";
}

}  // namespace

ServerChild::ServerChild(const std::vector<std::string>& args,
                         const std::vector<std::string>& environment, std::chrono::seconds timeout)
    : port_file_(UniquePortFile()) {
  std::remove(port_file_.c_str());
  std::vector<std::string> argv_strings = {SKINSERVE_SERVER_BINARY, "--listen", "127.0.0.1:0",
                                           "--port-file", port_file_};
  argv_strings.insert(argv_strings.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& s : argv_strings) argv.push_back(s.data());
  argv.push_back(nullptr);
  // The child's environment: this process's, with `environment` added or replacing a
  // variable of the same name. Built before fork: between fork and exec the child of a
  // threaded process may only call async-signal-safe functions (putenv may allocate).
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('=') + 1);
    const bool replaced = std::any_of(environment.begin(), environment.end(),
                                      [&](const std::string& a) { return a.starts_with(name); });
    if (!replaced) env_strings.push_back(entry);
  }
  env_strings.insert(env_strings.end(), environment.begin(), environment.end());
  std::vector<char*> envp;
  for (std::string& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);

  pid_ = fork();
  if (pid_ < 0) {
    error_ = "fork failed";
    return;
  }
  if (pid_ == 0) {
    execve(SKINSERVE_SERVER_BINARY, argv.data(), envp.data());
    _exit(127);
  }

  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int port = 0;
  while ((port = ReadPort(port_file_)) == 0) {
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      error_ = DescribeExit(status) + " before it wrote its port";
      return;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      error_ = "skinserve wrote no port within " + std::to_string(timeout.count()) + " s";
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  target_ = "127.0.0.1:" + std::to_string(port);
  // The port file is written once the server is SERVING: one health check confirms it.
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      deadline - std::chrono::steady_clock::now());
  const auto status = client::CheckHealth(*client::MakeChannel(target_),
                                          std::max(left, std::chrono::milliseconds(1000)));
  if (!status.ok()) error_ = "skinserve on " + target_ + " not SERVING: " + status.ToString();
}

ServerChild::~ServerChild() {
  Stop(SIGKILL);
  std::remove(port_file_.c_str());
}

int ServerChild::Stop(int signal) {
  if (pid_ <= 0) return -1;
  kill(pid_, signal);
  int status = 0;
  const pid_t reaped = waitpid(pid_, &status, 0);
  pid_ = -1;
  return reaped > 0 ? status : -1;
}

}  // namespace skinserve::testing
