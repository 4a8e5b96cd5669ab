// The upload attack of issue 27, reusable: uploads that declare a big mesh and then hold
// their streams open, sending nothing more (header-only) or a chunk now and then
// (slow-drip), each on a connection of its own. A server that sizes an upload by its
// header holds every declared mesh in full; a bounded one holds what was sent, within its
// upload budget. Used by skinserve-upload-attack and by the upload stress test.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <thread>

namespace skinserve::attack {

struct UploadAttackOptions {
  std::string target;
  int header_only = 16;  // uploads that send a header, then nothing
  int slow_drip = 4;     // uploads that send one chunk of positions every drip_interval
  uint32_t vertices = 4'000'000;
  uint32_t influences = 8;
  bool normals = true;
  std::size_t drip_chunk_bytes = 1 << 20;
  std::chrono::milliseconds drip_interval{2000};
  std::chrono::milliseconds hold{6000};  // how long a round holds its uploads open
  int connection_base = 1000;            // connection ids (MakeChannel) used: base + upload
};

// How a round's uploads ended, by gRPC status code name and the limit its message names
// ("RESOURCE_EXHAUSTED --max-uploads"), with one message of each.
struct UploadAttackRound {
  std::map<std::string, int> endings;
  std::map<std::string, std::string> messages;
  uint64_t drip_bytes_sent = 0;
};

// Opens every upload, holds them for `hold` (the slow ones sending), then cancels those
// the server has not ended and says how each ended.
UploadAttackRound RunUploadAttackRound(const UploadAttackOptions& options);

// The resident memory of a process (VmRSS), in MiB; 0 when it cannot be read.
uint64_t RssMb(pid_t pid);

// Samples a process's RSS every 50 ms on a thread of its own, from construction to Stop.
class PeakRssSampler {
 public:
  explicit PeakRssSampler(pid_t pid);
  ~PeakRssSampler() { Stop(); }
  // Stops sampling; the largest RSS seen, in MiB.
  uint64_t Stop();

 private:
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> peak_mb_{0};
  std::thread thread_;
};

}  // namespace skinserve::attack
