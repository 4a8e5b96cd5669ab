// SamplingPlan: how SamplingJob walks a clip, derived from its tracks when it is built
// (no bytes of its own: Serialize() and the id leave it out). Constant tracks are copied,
// LINEAR and STEP smallest-three rotations keyed at every clip time are decoded (and
// slerped) 4 at a time (SoA; 16-bit groups first, then packed ones: a group is one or the
// other), LINEAR 16-bit or packed vectors keyed at every time are lerped in one tight loop,
// CUBICSPLINE ones keyed at every time a track at a time with its components side by side;
// the rest (weights, tracks with their own key times) one track at a time.
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/animation/compact_clip.h"

namespace skinserve::animation {

struct SamplingPlan {
  struct Constant {
    uint16_t joint = 0;
    uint8_t offset = 0;  // of the value in the Transform's floats: 0, 3 (rotation) or 7
    float value[4] = {0, 0, 0, 0};
  };
  // Four rotation tracks (a last group may hold fewer: `lanes`).
  struct RotationGroup {
    uint32_t lanes = 0;
    uint16_t joint[4] = {0, 0, 0, 0};
    // Where the track's keys start: a byte offset into CompactClip::packed (packed[lane])
    // or into CompactClip::words' bytes; each key 3 components of bits[lane]. A group's
    // lanes are all 16-bit or all packed (MakeSamplingPlan groups them so).
    uint32_t bytes[4] = {0, 0, 0, 0};
    uint32_t bits[4] = {16, 16, 16, 16};
    uint8_t packed[4] = {0, 0, 0, 0};
    uint32_t largest[4] = {0, 0, 0, 0};  // CompactTrack::largest
    float min[4][3] = {};                // per lane, per stored slot: the range's start
    float step[4][3] = {};
  };
  struct Vector {
    uint16_t joint = 0;
    uint8_t path = 0;
    uint32_t bytes = 0;  // as RotationGroup's
    uint32_t bits = 16;
    uint8_t packed = 0;
    float min[3] = {0, 0, 0};
    float step[3] = {0, 0, 0};
  };
  // A CUBICSPLINE 16-bit translation, rotation or scale keyed at every clip time: its
  // components side by side (lanes past `width` hold 0).
  struct Cubic {
    uint16_t joint = 0;
    uint8_t path = 0;
    uint8_t width = 0;     // 3, or 4 (a rotation)
    uint32_t words = 0;    // CompactTrack::words: per key, in-tangent, value, out-tangent
    float min[3][4] = {};  // per column group (in-tangent, value, out-tangent), per component
    float step[3][4] = {};
  };
  // Joints some of whose translation, rotation and scale no track sets: they start from
  // the skeleton's rest (the others are written whole by their tracks). As runs of
  // consecutive joints, each copied at once (often all of them: exporters key most
  // translations and scales at their rest values, which the store leaves out).
  struct JointRun {
    uint16_t first = 0;
    uint16_t count = 0;
  };
  std::vector<JointRun> rest_runs;
  std::vector<Constant> constants;
  std::vector<RotationGroup> rotations;
  std::vector<RotationGroup> step_rotations;  // STEP: the key at or before the time
  std::vector<Vector> vectors;
  std::vector<Cubic> cubics;
  std::vector<uint32_t> others;  // track indices
};

SamplingPlan MakeSamplingPlan(const CompactClip& clip);

}  // namespace skinserve::animation
