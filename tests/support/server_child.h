// A real `skinserve` as a child process on a loopback port the kernel picks (--listen
// 127.0.0.1:0 --port-file), so a test never races other processes for a free port: a port
// guessed from the pid once collided with a connection's ephemeral port in CI.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <string>
#include <vector>

namespace skinserve::testing {

class ServerChild {
 public:
  // Starts SKINSERVE_SERVER_BINARY with `args` (besides --listen and --port-file) and
  // `environment` ("NAME=VALUE" each), and waits up to `timeout` until it serves.
  explicit ServerChild(const std::vector<std::string>& args = {"--log-level", "warn"},
                       const std::vector<std::string>& environment = {},
                       std::chrono::seconds timeout = std::chrono::seconds(60));
  // Kills the child (SIGKILL) if Stop() has not reaped it.
  ~ServerChild();
  ServerChild(const ServerChild&) = delete;
  ServerChild& operator=(const ServerChild&) = delete;

  // True once the server wrote its port and then answered a health check SERVING.
  bool ready() const { return error_.empty(); }
  // Why it is not ready: the child's exit, a timeout, or a failed fork.
  const std::string& error() const { return error_; }
  // "127.0.0.1:PORT"; empty when the server never wrote its port.
  const std::string& target() const { return target_; }
  pid_t pid() const { return pid_; }
  // Sends `signal` and reaps the child; returns its wait status (see waitpid), or -1 when
  // there was no child to reap.
  int Stop(int signal);

 private:
  pid_t pid_ = -1;
  std::string port_file_;
  std::string target_;
  std::string error_;
};

}  // namespace skinserve::testing
