// skinserve: the gRPC skinning server. main only wires options to the server.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <csignal>
#include <thread>

#include "server_options.h"
#include "skin_server.h"

namespace {

// The handler only writes the signal number to a pipe (async-signal-safe); a normal
// thread reads it and drains. Whichever thread the kernel picks gets the same result.
int signal_pipe[2] = {-1, -1};

void OnSignal(int signal) {
  const unsigned char byte = static_cast<unsigned char>(signal);
  [[maybe_unused]] const ssize_t written = write(signal_pipe[1], &byte, 1);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace skinserve::server;
  ServerOptions options;
  CLI::App app{"skinserve: remote linear blend skinning over gRPC (skinserve.v1.Skinning)"};
  AddServerOptions(app, options);
  app.set_version_flag("--version", "skinserve " SKINSERVE_VERSION);
  CLI11_PARSE(app, argc, argv);

  if (pipe(signal_pipe) != 0) {
    spdlog::error("cannot create the signal pipe");
    return 1;
  }
  struct sigaction action = {};
  action.sa_handler = OnSignal;
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGINT, &action, nullptr);

  auto server = SkinServer::Start(options);
  if (!server.ok()) {
    spdlog::error("{}", server.status().ToString());
    return 1;
  }
  std::thread([&] {
    unsigned char signal = 0;
    while (read(signal_pipe[0], &signal, 1) != 1) {
    }
    spdlog::info("{}: shutting down", signal == SIGTERM ? "SIGTERM" : "SIGINT");
    (*server)->Shutdown(
        std::chrono::milliseconds(static_cast<int64_t>(options.drain_seconds * 1000)));
  }).detach();
  (*server)->Wait();
  (*server)->Shutdown(std::chrono::milliseconds(0));
  return 0;
}
