// What the process-level tests read of a process: a command's output, a process' resident
// memory, and what the AddressSanitizer's quarantine adds to it.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

namespace skinserve::testing {

// stdout of `command` (run by the shell), whole.
std::string RunAndCapture(const std::string& command);

// The process' resident set, MiB (VmRSS of /proc/PID/status; 0 once it is gone).
uint64_t RssMb(pid_t pid);
// The same in KiB, for bounds of a few MB.
uint64_t RssKb(pid_t pid);

// How many descriptors the process has open (entries of /proc/PID/fd).
int OpenFdCount(pid_t pid);

// The TCP ports the process listens on (IPv4 and IPv6): its sockets (/proc/PID/fd) found
// in LISTEN state in /proc/PID/net/tcp and tcp6. For a server started on port 0.
std::vector<int> ListeningTcpPorts(pid_t pid);

// Under AddressSanitizer a process keeps up to 256 MB of freed memory in ASan's quarantine
// (its default quarantine_size_mb), which the allocator would otherwise reuse: memory
// bounds of the stress tests add it.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr uint64_t kSanitizerQuarantineMb = 256;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr uint64_t kSanitizerQuarantineMb = 256;
#else
inline constexpr uint64_t kSanitizerQuarantineMb = 0;
#endif
#else
inline constexpr uint64_t kSanitizerQuarantineMb = 0;
#endif

}  // namespace skinserve::testing
