#include "arrivals.h"

#include <algorithm>
#include <cmath>

namespace skinserve::load {

std::optional<Arrivals> ParseArrivals(const std::string& text) {
  if (text == "constant") return Arrivals::kConstant;
  if (text == "poisson") return Arrivals::kPoisson;
  return std::nullopt;
}

const char* ArrivalsName(Arrivals arrivals) {
  return arrivals == Arrivals::kPoisson ? "poisson" : "constant";
}

ArrivalSchedule::ArrivalSchedule(Arrivals arrivals, double rate, int stream, int streams,
                                 uint64_t seed)
    : arrivals_(arrivals),
      rate_(rate),
      offset_(static_cast<double>(stream) / std::max(streams, 1)),
      state_(seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(stream) + 1) {}

uint64_t ArrivalSchedule::NextBits() {
  uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double ArrivalSchedule::Next() {
  if (arrivals_ == Arrivals::kConstant) {
    return (static_cast<double>(frame_++) + offset_) / rate_;
  }
  // Inverse CDF of the exponential: -ln(U) / rate with U uniform in (0, 1] (53 bits).
  const double u = (static_cast<double>(NextBits() >> 11) + 1.0) * 0x1.0p-53;
  time_ += -std::log(u) / rate_;
  ++frame_;
  return time_;
}

}  // namespace skinserve::load
