// Palette: one affine 3x4 matrix per joint, row-major, 12 floats per joint; the implied
// fourth row is 0 0 0 1. Palettes travel as spans: a frame's palette is never copied twice.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "skinserve/model/status.h"

namespace skinserve {

inline constexpr std::size_t kFloatsPerJoint = 12;

// Checks that `palette` holds exactly 12 * joint_count finite floats. The error names the
// joint and the element, e.g. "palette[joint 3][row 1, col 2] is not finite (nan)".
Status ValidatePalette(std::span<const float> palette, uint32_t joint_count);

// Dual-quaternion skinning's contract: every joint matrix must be rigid, a rotation and a
// translation. Scale and shear are refused, not approximated: a dual quaternion cannot
// carry them, and dropping them silently would move vertices. The test on each joint's
// upper 3x3 R: every element of R^T R - I within kRigidTolerance (so column lengths within
// about 0.05% of 1 and columns within about 0.06 degrees of orthogonal), and det R > 0
// (a reflection is not a rotation). The error names the joint and what is wrong, e.g.
// "palette[joint 3] is not rigid: column 0 has length 1.2 (scale) ...". Call it on a
// palette that passed ValidatePalette.
inline constexpr double kRigidTolerance = 1e-3;
Status ValidateRigidPalette(std::span<const float> palette);

}  // namespace skinserve
