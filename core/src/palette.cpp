#include "skinserve/core/palette.h"

#include <fmt/format.h>
#include <cmath>

namespace skinserve {

Status ValidatePalette(std::span<const float> palette, uint32_t joint_count) {
  const std::size_t expected = kFloatsPerJoint * joint_count;
  if (palette.size() != expected) {
    return InvalidArgument(
        fmt::format("palette holds {} floats; expected 12 * joint_count = {} (joint_count {})",
                    palette.size(), expected, joint_count));
  }
  for (std::size_t i = 0; i < palette.size(); ++i) {
    if (!std::isfinite(palette[i])) {
      const std::size_t element = i % kFloatsPerJoint;
      return InvalidArgument(fmt::format("palette[joint {}][row {}, col {}] = {} is not finite",
                                         i / kFloatsPerJoint, element / 4, element % 4,
                                         palette[i]));
    }
  }
  return Status::Ok();
}

}  // namespace skinserve
