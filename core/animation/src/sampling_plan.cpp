#include "sampling_plan.h"

namespace skinserve::animation {
namespace {

bool EveryKey(const CompactTrack& t) {
  return t.key_times == kAllKeyTimes && t.interpolation == Interpolation::kLinear;
}

bool IsPacked(const CompactTrack& t) {
  return t.format == TrackFormat::kRangePacked || t.format == TrackFormat::kSmallestThreePacked;
}

// Where a 16-bit or packed track's keys start, in bytes of the array that holds them.
uint32_t KeyBytes(const CompactTrack& t) { return IsPacked(t) ? t.words : 2 * t.words; }

// A group's empty lanes repeat its first track (decoded and slerped like the others,
// never written), so the 4-wide code needs no lane checks.
void PadLastGroup(std::vector<SamplingPlan::RotationGroup>& groups) {
  if (groups.empty()) return;
  SamplingPlan::RotationGroup& g = groups.back();
  for (uint32_t lane = g.lanes; lane < 4; ++lane) {
    g.joint[lane] = g.joint[0];
    g.bytes[lane] = g.bytes[0];
    g.bits[lane] = g.bits[0];
    g.packed[lane] = g.packed[0];
    g.largest[lane] = g.largest[0];
    for (int c = 0; c < 3; ++c) {
      g.min[lane][c] = g.min[0][c];
      g.step[lane][c] = g.step[0][c];
    }
  }
}

void AddRotation(const CompactClip& clip, const CompactTrack& t,
                 std::vector<SamplingPlan::RotationGroup>& groups) {
  if (groups.empty() || groups.back().lanes == 4 ||
      groups.back().packed[0] != (IsPacked(t) ? 1 : 0)) {
    PadLastGroup(groups);
    groups.emplace_back();
  }
  SamplingPlan::RotationGroup& g = groups.back();
  const uint32_t lane = g.lanes++;
  g.joint[lane] = t.joint;
  g.bytes[lane] = KeyBytes(t);
  g.bits[lane] = t.bits;
  g.packed[lane] = IsPacked(t) ? 1 : 0;
  g.largest[lane] = t.largest;
  for (int s = 0; s < 3; ++s) {
    g.min[lane][s] = clip.floats[t.floats + 2 * s];
    g.step[lane][s] = clip.floats[t.floats + 2 * s + 1];
  }
}

SamplingPlan::Cubic MakeCubic(const CompactClip& clip, const CompactTrack& t) {
  SamplingPlan::Cubic c;
  c.joint = t.joint;
  c.path = static_cast<uint8_t>(t.path);
  c.width = static_cast<uint8_t>(t.width);
  c.words = t.words;
  for (uint32_t group = 0; group < 3; ++group) {
    for (uint32_t k = 0; k < t.width; ++k) {
      const uint32_t column = group * t.width + k;
      c.min[group][k] = clip.floats[t.floats + 2 * column];
      c.step[group][k] = clip.floats[t.floats + 2 * column + 1];
    }
  }
  return c;
}

}  // namespace

SamplingPlan MakeSamplingPlan(const CompactClip& clip) {
  SamplingPlan plan;
  std::vector<uint8_t> paths(clip.joint_count, 0);        // bit per TrackPath a track sets
  std::vector<uint32_t> rotations[2], step_rotations[2];  // 16-bit, packed: track indices
  for (uint32_t i = 0; i < clip.tracks.size(); ++i) {
    const CompactTrack& t = clip.tracks[i];
    const uint8_t path = static_cast<uint8_t>(t.path);
    const bool smallest_three =
        t.format == TrackFormat::kSmallestThree16 || t.format == TrackFormat::kSmallestThreePacked;
    if (t.path != TrackPath::kWeights) paths[t.joint] |= static_cast<uint8_t>(1u << path);
    if (t.path == TrackPath::kWeights) {
      plan.others.push_back(i);
    } else if (t.format == TrackFormat::kConstant) {
      const uint8_t offset =
          t.path == TrackPath::kTranslation ? 0 : (t.path == TrackPath::kRotation ? 3 : 7);
      SamplingPlan::Constant c{t.joint, offset, {0, 0, 0, 0}};
      for (uint32_t k = 0; k < t.width; ++k) c.value[k] = clip.floats[t.floats + k];
      plan.constants.push_back(c);
    } else if (smallest_three && EveryKey(t)) {
      rotations[IsPacked(t) ? 1 : 0].push_back(i);
    } else if (smallest_three && t.key_times == kAllKeyTimes &&
               t.interpolation == Interpolation::kStep) {
      step_rotations[IsPacked(t) ? 1 : 0].push_back(i);
    } else if ((t.format == TrackFormat::kRange16 || t.format == TrackFormat::kRangePacked) &&
               EveryKey(t) && t.path != TrackPath::kRotation) {
      SamplingPlan::Vector v{
          t.joint, path, KeyBytes(t), t.bits, IsPacked(t) ? uint8_t{1} : uint8_t{0}, {}, {}};
      for (int c = 0; c < 3; ++c) {
        v.min[c] = clip.floats[t.floats + 2 * c];
        v.step[c] = clip.floats[t.floats + 2 * c + 1];
      }
      plan.vectors.push_back(v);
    } else if (t.format == TrackFormat::kRange16 && t.key_times == kAllKeyTimes &&
               t.interpolation == Interpolation::kCubicSpline && (t.width == 3 || t.width == 4)) {
      plan.cubics.push_back(MakeCubic(clip, t));
    } else {
      plan.others.push_back(i);
    }
  }
  for (uint32_t j = 0; j < clip.joint_count; ++j) {
    if (paths[j] == 7) continue;
    std::vector<SamplingPlan::JointRun>& runs = plan.rest_runs;
    if (!runs.empty() && runs.back().first + runs.back().count == j) {
      ++runs.back().count;
    } else {
      runs.push_back({static_cast<uint16_t>(j), 1});
    }
  }
  for (int packed = 0; packed < 2; ++packed) {  // 16-bit groups, then packed ones
    for (uint32_t i : rotations[packed]) AddRotation(clip, clip.tracks[i], plan.rotations);
    for (uint32_t i : step_rotations[packed])
      AddRotation(clip, clip.tracks[i], plan.step_rotations);
  }
  PadLastGroup(plan.rotations);
  PadLastGroup(plan.step_rotations);
  return plan;
}

}  // namespace skinserve::animation
