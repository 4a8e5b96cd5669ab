// skinserve: the gRPC skinning server. main only wires options to the server.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <csignal>
#include <thread>

#include "server_options.h"
#include "skin_server.h"

int main(int argc, char** argv) {
  using namespace skinserve::server;
  ServerOptions options;
  CLI::App app{"skinserve: remote linear blend skinning over gRPC (skinserve.v1.Skinning)"};
  AddServerOptions(app, options);
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::from_str(options.log_level));

  // SIGTERM and SIGINT are taken by one thread with sigwait, never by gRPC's threads.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto server = SkinServer::Start(options);
  if (!server.ok()) {
    spdlog::error("{}", server.status().ToString());
    return 1;
  }
  std::thread([&] {
    int signal = 0;
    sigwait(&signals, &signal);
    spdlog::info("{}: shutting down", signal == SIGTERM ? "SIGTERM" : "SIGINT");
    (*server)->Shutdown(
        std::chrono::milliseconds(static_cast<int64_t>(options.drain_seconds * 1000)));
  }).detach();
  (*server)->Wait();
  (*server)->Shutdown(std::chrono::milliseconds(0));
  return 0;
}
