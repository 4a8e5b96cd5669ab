// skinserve-upload-attack: the upload attack of issue 27 against a running server, with
// the server's peak RSS per round (read from /proc, so on the same host):
//
//   skinserve --listen 127.0.0.1:0 --port-file /tmp/port & pid=$!
//   source scripts/lib/port-file.sh; port=$(wait_for_port /tmp/port $pid)
//   skinserve-upload-attack --target 127.0.0.1:$port --server-pid $pid; kill $pid
//
// Works against any skinserve, bounded or not, so the numbers before and after compare.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <thread>

#include "skinserve/cli/version.h"
#include "upload_attack.h"

int main(int argc, char** argv) {
  using namespace skinserve::attack;
  UploadAttackOptions o;
  int server_pid = 0;
  int rounds = 3;
  double hold_seconds = 6, drip_seconds = 2, settle_seconds = 2;
  CLI::App app{
      "skinserve-upload-attack: header-only and slow-drip uploads held open against a "
      "running server; prints its peak RSS per round"};
  app.add_option("--target", o.target, "the server's address:port")->required();
  app.add_option("--server-pid", server_pid, "its pid, to read its RSS (/proc/PID/status)")
      ->required();
  app.add_option("--rounds", rounds, "rounds of the attack")->capture_default_str();
  app.add_option("--header-only", o.header_only, "uploads that send a header, then nothing")
      ->capture_default_str();
  app.add_option("--slow-drip", o.slow_drip, "uploads that send a chunk every --drip-seconds")
      ->capture_default_str();
  app.add_option("--vertices", o.vertices, "vertices each upload declares")->capture_default_str();
  app.add_option("--influences", o.influences, "influences each upload declares")
      ->capture_default_str();
  app.add_option("--normals", o.normals, "whether each upload declares normals")
      ->capture_default_str();
  app.add_option("--drip-chunk-bytes", o.drip_chunk_bytes, "bytes of each slow-drip chunk")
      ->capture_default_str();
  app.add_option("--drip-seconds", drip_seconds, "between a slow-drip upload's chunks")
      ->capture_default_str();
  app.add_option("--hold-seconds", hold_seconds, "how long each round holds its uploads")
      ->capture_default_str();
  app.add_option("--settle-seconds", settle_seconds, "pause after each round")
      ->capture_default_str();
  skinserve::cli::AddVersionFlag(app, "skinserve-upload-attack");
  CLI11_PARSE(app, argc, argv);
  const auto ms = [](double s) { return std::chrono::milliseconds(static_cast<int64_t>(s * 1e3)); };
  o.hold = ms(hold_seconds);
  o.drip_interval = ms(drip_seconds);

  fmt::print("server RSS before: {} MB\n", RssMb(server_pid));
  uint64_t peak_of_all = 0;
  for (int round = 0; round < rounds; ++round) {
    PeakRssSampler sampler(server_pid);
    const UploadAttackRound result = RunUploadAttackRound(o);
    std::this_thread::sleep_for(ms(settle_seconds));
    const uint64_t peak = sampler.Stop();
    peak_of_all = std::max(peak_of_all, peak);
    fmt::print("round {}: server RSS peak {} MB, after {} MB; slow-drip sent {:.1f} MiB\n", round,
               peak, RssMb(server_pid), result.drip_bytes_sent / 1048576.0);
    for (const auto& [name, count] : result.endings) {
      fmt::print("  {} x {}: {}\n", count, name, result.messages.at(name));
    }
  }
  fmt::print("peak RSS over {} rounds: {} MB\n", rounds, peak_of_all);
  return 0;
}
