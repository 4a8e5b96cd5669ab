// The check of a pose frame's answer (--animate with --check-every): the clip evaluated in
// float64 at the frame's time (PoseWorkload::ReferencePalette, from the clip's keys, never
// the server's compact store), the mesh morphed by the frame's weights and skinned in
// double with that palette (--animate FILE: the file's own primitive and channels as the
// check's reader reads them, gltf_reference.h), and the answer held to the pose tests' bound
// (tests/server/pose_service_test.cpp): each vertex within 2e-5 + 3e-4 (|rest| + |posed|)
// (the compact clip's joints are within 0.01 mm + 1e-4 relative, its rotations' elements
// within 1e-4, of the float64 clip; float32 skinning adds rounding), plus the answer
// encoding's stated error; with --clip-error-mm E above the default 0.01 mm, the pose part
// of the bound times E / 0.01 (the clip's joints and 3x3 elements are held to E).
#pragma once

#include <span>

#include "skinserve/encoding/vertex_encoding.h"
#include "workload.h"

namespace skinserve::load {

// One instance's decoded answer of a pose frame.
struct PoseAnswer {
  uint64_t frame = 0;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  Bounds bounds;                     // snorm16: the box the positions were quantized to
  std::span<const float> positions;  // 3 a vertex
  std::span<const float> normals;    // 3 a vertex, or empty when the workload has none
  std::span<const float> tangents;   // 4 a vertex, or empty when the workload has none
};

// The largest error over the answer's vertices as a fraction of its bound (infinite for a
// NaN or a wrong length): within the bound while <= 1. Positions: the Euclidean distance
// against 2e-5 + 3e-4 (|rest| + |posed|) + the encoding's per-axis error; normals and
// tangents' x y z (unit vectors): 2e-5 + 3e-4 * 2, times the morph deltas' magnification,
// + the encoding's; tangents' w (the handedness) must equal the rest's.
double PoseAnswerError(const Workload& w, const PoseAnswer& answer);

}  // namespace skinserve::load
