// The float64 reference every backend is checked against: the paper's equations 3 and 4
// written as plainly as possible, in double, sharing no code with any backend.
#pragma once

#include <span>
#include <vector>

#include "skinserve/model/mesh.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/skinning_method.h"

namespace skinserve {

struct ReferenceFrame {
  std::vector<double> positions;  // 3 * V
  std::vector<double> normals;    // 3 * V, or empty when the mesh has none
  std::vector<double> tangents;   // 4 * V (x y z w), or empty when the mesh has none
};

// The rest arrays a frame skins, in double: the mesh's, plus sum_t weight_t * delta_t of
// the frame's morph targets (morph_reference.cpp, written apart from the engine's morph
// stage: dense, target by target). `normals` is empty when the mesh has none.
ReferenceFrame ReferenceMorph(const Mesh& mesh, std::span<const MorphWeight> morph);

// What float32 rounding of a morphed frame is relative to: per position coordinate
// |rest| + sum_t |w_t delta_t|, and the largest (|n| + sum_t |w_t| |dn_t|) / |morphed n|
// over the vertices (at least 1).
struct MorphMagnitudes {
  std::vector<double> positions;  // 3 * V
  double normal_magnification = 1;
  double tangent_magnification = 1;  // the same for tangents' xyz
};
MorphMagnitudes ReferenceMorphMagnitudes(const Mesh& mesh, std::span<const MorphWeight> morph);

// Linear blend skinning in double of the mesh's rest arrays morphed by `morph` (none: the
// rest arrays as they are). A tangent's xyz is transformed and normalised as the normal,
// its w copied.
ReferenceFrame ReferenceSkin(const Mesh& mesh, std::span<const float> palette,
                             std::span<const MorphWeight> morph = {});
// The same with a float64 palette (a pose evaluated in double: pose_reference.h).
ReferenceFrame ReferenceSkin(const Mesh& mesh, std::span<const double> palette,
                             std::span<const MorphWeight> morph = {});

// The float64 dual-quaternion reference (dual_quaternion_reference.cpp), written apart
// from the kernels on glm's dual quaternions: each joint matrix to a unit dual quaternion,
// the vertex's B of them blended with signs against the first influence, normalised,
// applied to the position; the normal and the tangent's xyz rotated by the blended
// rotation, the tangent's w copied. The palette must
// be rigid (ValidateRigidPalette).
ReferenceFrame ReferenceSkinDualQuaternion(const Mesh& mesh, std::span<const float> palette,
                                           std::span<const MorphWeight> morph = {});

struct Deviation {
  double max_position_error = 0;  // max |backend - reference| over every coordinate
  double max_normal_error = 0;
  double max_tangent_error = 0;  // over x y z w (w must match exactly: its error is 0 or >= 2)
  std::size_t worst_vertex = 0;
  double position_tolerance = 0;  // what float32 rounding allows for this mesh and pose
  double normal_tolerance = 0;
  double tangent_tolerance = 0;
  bool within_tolerance() const {
    return max_position_error <= position_tolerance && max_normal_error <= normal_tolerance &&
           max_tangent_error <= tangent_tolerance;
  }
};

// Compares float32 results with the reference. Tolerance: positions 1e-5 * (1 + S), where
// S bounds |M p| over the frame (max |p| * max row sum of |M| + max |t|); normals 1e-5
// absolute (they are unit vectors). `normals` may be empty to skip them. A NaN anywhere
// counts as an infinite error. `method` picks the reference; the tolerance is the same.
// With morph targets, max |p| is over the morphed terms (|p| + sum |w d| per coordinate),
// and the normal tolerance is 1e-5 * max over vertices of (|n| + sum |w dn|) / |morphed n|:
// float32 rounds the sum's terms, and a normal that the deltas shorten magnifies that.
// `tangents` (4 floats per vertex) may be empty to skip them; their xyz take the normals'
// tolerance (with the tangent deltas' magnification), their w must equal the rest's.
Deviation CompareWithReference(const Mesh& mesh, std::span<const float> palette,
                               std::span<const float> positions, std::span<const float> normals,
                               SkinningMethod method = SkinningMethod::kLinear,
                               std::span<const MorphWeight> morph = {},
                               std::span<const float> tangents = {});

}  // namespace skinserve
