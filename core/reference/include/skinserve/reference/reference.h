// The float64 reference every backend is checked against: the paper's equations 3 and 4
// written as plainly as possible, in double, sharing no code with any backend.
#pragma once

#include <span>
#include <vector>

#include "skinserve/model/mesh.h"
#include "skinserve/model/skinning_method.h"

namespace skinserve {

struct ReferenceFrame {
  std::vector<double> positions;  // 3 * V
  std::vector<double> normals;    // 3 * V, or empty when the mesh has none
};

ReferenceFrame ReferenceSkin(const Mesh& mesh, std::span<const float> palette);

// The float64 dual-quaternion reference (dual_quaternion_reference.cpp), written apart
// from the kernels on glm's dual quaternions: each joint matrix to a unit dual quaternion,
// the vertex's B of them blended with signs against the first influence, normalised,
// applied to the position; the normal rotated by the blended rotation. The palette must
// be rigid (ValidateRigidPalette).
ReferenceFrame ReferenceSkinDualQuaternion(const Mesh& mesh, std::span<const float> palette);

struct Deviation {
  double max_position_error = 0;  // max |backend - reference| over every coordinate
  double max_normal_error = 0;
  std::size_t worst_vertex = 0;
  double position_tolerance = 0;  // what float32 rounding allows for this mesh and pose
  double normal_tolerance = 0;
  bool within_tolerance() const {
    return max_position_error <= position_tolerance && max_normal_error <= normal_tolerance;
  }
};

// Compares float32 results with the reference. Tolerance: positions 1e-5 * (1 + S), where
// S bounds |M p| over the frame (max |p| * max row sum of |M| + max |t|); normals 1e-5
// absolute (they are unit vectors). `normals` may be empty to skip them. A NaN anywhere
// counts as an infinite error. `method` picks the reference; the tolerance is the same.
Deviation CompareWithReference(const Mesh& mesh, std::span<const float> palette,
                               std::span<const float> positions, std::span<const float> normals,
                               SkinningMethod method = SkinningMethod::kLinear);

}  // namespace skinserve
