// Calls f(std::integral_constant<int, B>{}) for B = `influences` (1..kMaxInfluences), so
// each skinning loop is compiled once per influence count with B a constant.
#pragma once

#include <cstdint>
#include <type_traits>

namespace skinserve {

template <typename F>
void WithInfluences(uint32_t influences, F&& f) {
  switch (influences) {
    case 1:
      return f(std::integral_constant<int, 1>{});
    case 2:
      return f(std::integral_constant<int, 2>{});
    case 3:
      return f(std::integral_constant<int, 3>{});
    case 4:
      return f(std::integral_constant<int, 4>{});
    case 5:
      return f(std::integral_constant<int, 5>{});
    case 6:
      return f(std::integral_constant<int, 6>{});
    case 7:
      return f(std::integral_constant<int, 7>{});
    case 8:
      return f(std::integral_constant<int, 8>{});
  }
}

}  // namespace skinserve
