// Skeleton: the joint hierarchy (parents before children), its rest pose and the skin's
// palette mapping with inverse bind matrices. Jobs take it by pointer and never change it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

inline constexpr uint32_t kMaxSkeletonJoints = 1024;

struct Skeleton {
  // parents[i] < i, or -1 for a root: one pass over the joints composes model matrices.
  std::vector<int16_t> parents;
  std::vector<Transform> rest;     // one per joint: the pose of a joint no track animates
  std::vector<std::string> names;  // empty, or one per joint (for messages and tools)
  // Palette entry p is model(palette_joints[p]) * inverse_bind[p]: a glTF skin's joints
  // are a subset of the hierarchy (ancestors such as an armature node are not in it).
  std::vector<uint16_t> palette_joints;
  std::vector<Affine> inverse_bind;

  uint32_t joint_count() const { return static_cast<uint32_t>(parents.size()); }
  uint32_t palette_size() const { return static_cast<uint32_t>(palette_joints.size()); }
};

// INVALID_ARGUMENT naming the field: joint count 1..kMaxSkeletonJoints, parents before
// children, rest and names sized, rest finite with unit quaternions, palette joints in
// range, one finite inverse bind per palette entry.
Status ValidateSkeleton(const Skeleton& skeleton);

}  // namespace skinserve::animation
