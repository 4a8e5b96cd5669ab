// The limits the watchdogs enforce (idle streams, idle and overdue uploads) and how often they
// look: a quarter of the limit, between 1 ms and 250 ms, so a limit is passed by at most a
// quarter of itself.
#pragma once

#include <algorithm>
#include <chrono>

namespace skinserve::server {

// A limit given in seconds, at most 1e9 s (31 years) so that the limit, and now less it, stay
// in range.
inline std::chrono::nanoseconds LimitNanoseconds(double seconds) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
      std::chrono::duration<double>(std::min(seconds, 1e9)));
}

inline std::chrono::nanoseconds WatchdogPeriod(std::chrono::nanoseconds limit) {
  return std::clamp<std::chrono::nanoseconds>(limit / 4, std::chrono::milliseconds(1),
                                              std::chrono::milliseconds(250));
}

}  // namespace skinserve::server
