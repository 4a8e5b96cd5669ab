// Checks a runtime pose against pose_reference's float64 evaluation of the original
// channels, within a stated bound: every joint's model matrix and palette entry (a point
// it moves within `absolute` + `relative` |the reference point|, each 3x3 element within
// `rotation`), and the morph weights within 1e-4. Shared by the target
// (pose_accuracy_test) and the clip store's chosen tolerances (clip_tolerance_test).
#pragma once

#include <string>

#include "pose_reference.h"

namespace skinserve::testing {

struct PoseBound {
  double absolute = 1e-5;  // metres: 0.01 mm, the files being in metres
  double relative = 1e-4;
  double rotation = 1e-4;  // each element of a matrix's 3x3 part
};

// The largest error seen, each as a share of its bound (weights: absolute).
struct Worst {
  double position = 0, palette = 0, rotation = 0, weight = 0;
};

// The 3x3 part of `m` (12 floats, row-major 3x4) against `ref`'s, within bound.rotation.
void ExpectRotationNear(const float* m, const double* ref, const PoseBound& bound,
                        const std::string& what, Worst& worst);
// Point `p` moved by `m` and by `ref`: within absolute + relative |ref's point|. Returns the
// error's share of that bound.
double ExpectPointNear(const float* m, const double* ref, const double p[3], const PoseBound& bound,
                       const std::string& what);
// Every joint's model matrix and palette entry of `pose` against the reference at t.
void ExpectPoseMatches(const PoseCase& c, const RuntimePose& pose, double t, const PoseBound& bound,
                       Worst& worst);

}  // namespace skinserve::testing
