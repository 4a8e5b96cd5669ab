#include "sampling_plan.h"

namespace skinserve::animation {
namespace {

bool EveryKey(const CompactTrack& t) {
  return t.key_times == kAllKeyTimes && t.interpolation == Interpolation::kLinear;
}

void AddRotation(const CompactClip& clip, const CompactTrack& t, SamplingPlan& plan) {
  if (plan.rotations.empty() || plan.rotations.back().lanes == 4) plan.rotations.emplace_back();
  SamplingPlan::RotationGroup& g = plan.rotations.back();
  const uint32_t lane = g.lanes++;
  g.joint[lane] = t.joint;
  g.words[lane] = t.words;
  g.largest[lane] = t.largest;
  for (int s = 0; s < 3; ++s) {
    g.min[lane][s] = clip.floats[t.floats + 2 * s];
    g.step[lane][s] = clip.floats[t.floats + 2 * s + 1];
  }
}

}  // namespace

SamplingPlan MakeSamplingPlan(const CompactClip& clip) {
  SamplingPlan plan;
  for (uint32_t i = 0; i < clip.tracks.size(); ++i) {
    const CompactTrack& t = clip.tracks[i];
    const uint8_t path = static_cast<uint8_t>(t.path);
    if (t.path == TrackPath::kWeights) {
      plan.others.push_back(i);
    } else if (t.format == TrackFormat::kConstant) {
      SamplingPlan::Constant c{t.joint, path, {0, 0, 0, 0}};
      for (uint32_t k = 0; k < t.width; ++k) c.value[k] = clip.floats[t.floats + k];
      plan.constants.push_back(c);
    } else if (t.format == TrackFormat::kSmallestThree16 && EveryKey(t)) {
      AddRotation(clip, t, plan);
    } else if (t.format == TrackFormat::kRange16 && EveryKey(t) && t.path != TrackPath::kRotation) {
      SamplingPlan::Vector v{t.joint, path, t.words, {}, {}};
      for (int c = 0; c < 3; ++c) {
        v.min[c] = clip.floats[t.floats + 2 * c];
        v.step[c] = clip.floats[t.floats + 2 * c + 1];
      }
      plan.vectors.push_back(v);
    } else {
      plan.others.push_back(i);
    }
  }
  // A last group's empty lanes repeat its first track (decoded and slerped like the others,
  // never written), so the 4-wide code needs no lane checks.
  if (!plan.rotations.empty()) {
    SamplingPlan::RotationGroup& g = plan.rotations.back();
    for (uint32_t lane = g.lanes; lane < 4; ++lane) {
      g.joint[lane] = g.joint[0];
      g.words[lane] = g.words[0];
      g.largest[lane] = g.largest[0];
      for (int c = 0; c < 3; ++c) {
        g.min[lane][c] = g.min[0][c];
        g.step[lane][c] = g.step[0][c];
      }
    }
  }
  return plan;
}

}  // namespace skinserve::animation
