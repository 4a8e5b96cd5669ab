// splitmix64: tiny, fast and identical on every platform (std:: distributions are not); the
// synthetic meshes, palettes and morph targets draw from it so that a seed means one input.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace skinserve::synthetic {

class Random {
 public:
  explicit Random(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  std::array<double, 3> UnitVector() {
    const double z = Uniform(-1, 1);
    const double phi = Uniform(0, 2 * std::numbers::pi);
    const double r = std::sqrt(1 - z * z);
    return {r * std::cos(phi), r * std::sin(phi), z};
  }

 private:
  uint64_t state_;
};

}  // namespace skinserve::synthetic
