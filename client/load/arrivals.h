// When an open-loop stream sends its frames: evenly spaced (streams staggered so that
// together they send evenly too) or a Poisson process (exponential gaps from a seeded
// generator), as perf_analyzer's and ghz's constant and Poisson request distributions.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace skinserve::load {

enum class Arrivals { kConstant, kPoisson };

std::optional<Arrivals> ParseArrivals(const std::string& text);
const char* ArrivalsName(Arrivals arrivals);

// The send times of one stream of `streams`, in seconds from the run's start.
//   constant: frame k at (k + stream / streams) / rate: each stream every 1 / rate, the
//             streams offset by 1 / (rate * streams), so that all streams together send
//             every 1 / (rate * streams) rather than in bursts of `streams` frames.
//   poisson:  gaps drawn from Exp(rate) with a generator seeded from (seed, stream): the
//             same seed gives the same schedule; each stream independent, so together a
//             Poisson process of rate * streams.
class ArrivalSchedule {
 public:
  ArrivalSchedule(Arrivals arrivals, double rate, int stream, int streams, uint64_t seed);
  // The next frame's time (the first call gives frame 0's).
  double Next();

 private:
  // splitmix64: a fully specified generator (std:: distributions differ by library).
  uint64_t NextBits();

  Arrivals arrivals_;
  double rate_;
  double offset_;  // constant: this stream's stagger
  uint64_t frame_ = 0;
  double time_ = 0;  // poisson: the last frame's time
  uint64_t state_;
};

}  // namespace skinserve::load
