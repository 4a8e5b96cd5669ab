// Test cases for the animation runtime: a skeleton and raw clip, beside an independent
// float64 model of the same original channels (tests/character/gltf_test_support: its own
// glTF reading, slerp, Hermite and hierarchy), and what the runtime computes from them.
#pragma once

#include <string>
#include <vector>

#include "gltf_test_support.h"
#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/sampling_job.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/animation/synthetic_rig.h"

namespace skinserve::testing {

// A morph weights channel as the file keys it, in double.
struct RefWeights {
  int target = -1;
  std::string interpolation;
  std::size_t width = 0;
  std::vector<double> times, values;
};

struct PoseCase {
  std::string label;
  animation::Skeleton skeleton;
  animation::RawClip raw;
  RefCharacter ref;  // joints: the palette's nodes
  RefClip ref_clip;
  std::vector<int> nodes;  // ref node of each skeleton joint
  std::vector<RefWeights> weights;
};

// tests/assets/gltf/<file>, its skin 0 and clip `clip`.
PoseCase AssetCase(const std::string& file, std::size_t clip);
// MakeSyntheticRig(joints).
PoseCase SyntheticCase(uint32_t joints);

struct RuntimePose {
  std::vector<animation::Affine> model;
  std::vector<float> palette;
  std::vector<float> weights;
};
RuntimePose RunPose(const PoseCase& c, const animation::CompactClip& clip, float time,
                    animation::TimeMode mode = animation::TimeMode::kClamp,
                    animation::SamplingContext* context = nullptr);

// The reference at `t` (clamped): model matrices of the skeleton's joints, then the
// palette, 12 doubles each, row-major; morph weights in the clip's track order.
std::vector<double> RefModel(const PoseCase& c, double t);
std::vector<double> RefWeightsAt(const PoseCase& c, double t);

// The angle between two rotations (x y z w), well conditioned for tiny angles: both
// normalised in double, on one hemisphere, 4 asin(|a - b| / 2).
double RotationAngle(const float* a, const double* b);

// glTF's float bytes of a clip: each distinct key-time array once (files share one input
// accessor between channels) and every channel's values, 4 bytes a float.
std::size_t GltfFloatBytes(const animation::RawClip& raw);

// Times on keys, between keys, before and after the clip.
std::vector<double> SampleTimes(const PoseCase& c);

}  // namespace skinserve::testing
