// skinserve: the gRPC skinning server. main only wires options to the server.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <malloc.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "options/server_options.h"
#include "rpc/skin_server.h"
#include "skinserve/cli/config_file.h"
#include "skinserve/cli/version.h"

namespace {

// The handler only writes the signal number to a pipe (async-signal-safe); a normal
// thread reads it and drains. Whichever thread the kernel picks gets the same result.
int signal_pipe[2] = {-1, -1};

void OnSignal(int signal) {
  const unsigned char byte = static_cast<unsigned char>(signal);
  [[maybe_unused]] const ssize_t written = write(signal_pipe[1], &byte, 1);
}

// glibc serves allocations above a dynamic threshold (128 KiB at first) with fresh mmaps
// and trims the heap top eagerly, so gRPC's per-message buffers of a few hundred KiB
// page-fault on every frame (7-12 minor faults per 25k-vertex frame measured; 1-1.3 with
// these settings, fewer than jemalloc's 8 or mimalloc's 19: see
// docs/decisions/0004-allocator-glibc-tuned.md). Messages are at most ~1 MiB, so 4 MiB keeps them
// on the heap while large per-stream buffers are still mapped and returned when their stream ends.
// GLIBC_TUNABLES, when set, wins.
void TuneMalloc() {
  if (std::getenv("GLIBC_TUNABLES") != nullptr) return;
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
}

// Written to a temporary name and renamed, so a reader never sees a half-written number.
bool WritePortFile(const std::string& path, int port) {
  const std::string temporary = path + ".tmp";
  FILE* file = std::fopen(temporary.c_str(), "w");
  if (file == nullptr) return false;
  const bool written = std::fprintf(file, "%d\n", port) > 0;
  if (std::fclose(file) != 0 || !written) return false;
  return std::rename(temporary.c_str(), path.c_str()) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace skinserve::server;
  ServerOptions options;
  CLI::App app{"skinserve: remote linear blend skinning over gRPC (skinserve.v1.Skinning)"};
  AddServerOptions(app, options);
  skinserve::cli::AddVersionFlag(app, "skinserve");
  skinserve::cli::AddConfigFile(app, "SKINSERVE_CONFIG");
  if (const auto exit_code = skinserve::cli::ParseCommandLine(app, argc, argv)) return *exit_code;
  if (options.print_memory_envelope) {
    const MemoryEnvelope envelope = options.Envelope();
    const skinserve::Status fits = envelope.Check();
    std::printf("memory envelope:\n%s\n%s\n", envelope.Describe().c_str(),
                fits.ok() ? "fits" : "does not fit");
    return fits.ok() ? 0 : 1;
  }
  TuneMalloc();

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
  if (!options.port_file.empty() && !WritePortFile(options.port_file, (*server)->port())) {
    spdlog::error("--port-file: cannot write {}", options.port_file);
    (*server)->Shutdown(std::chrono::milliseconds(0));
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
