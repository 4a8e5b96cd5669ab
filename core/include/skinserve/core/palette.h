// Palette: one affine 3x4 matrix per joint, row-major, 12 floats per joint; the implied
// fourth row is 0 0 0 1. Palettes travel as spans: a frame's palette is never copied twice.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "skinserve/core/status.h"

namespace skinserve {

inline constexpr std::size_t kFloatsPerJoint = 12;

// Checks that `palette` holds exactly 12 * joint_count finite floats. The error names the
// joint and the element, e.g. "palette[joint 3][row 1, col 2] is not finite (nan)".
Status ValidatePalette(std::span<const float> palette, uint32_t joint_count);

}  // namespace skinserve
