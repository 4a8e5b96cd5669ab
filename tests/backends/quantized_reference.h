// The float64 references of a quantized rest stream (quantized_rest.h), shared by the
// CPU backends' test (quantized_rest_test.cpp) and the OpenCL one
// (tests/opencl/opencl_quantized_test.cpp):
//  1. on the DEQUANTIZED input (offset + scale * q in float64, q / steps weights, the last
//     1 - their sum, snorm16 normals): float32 rounding only (FloatTolerance; normals 1e-5);
//  2. on the ORIGINAL float input: the stated bound, per output coordinate r
//       sum_k |M[r][k]| * scale_k / 2                         (positions, half a step)
//     + sum_{i < B-1} (1 / steps) * |((M_i - M_last) p)[r]|    (weights, < 1 step each)
//     + FloatTolerance,
//     with M the matrix blended with the decoded weights.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "reference_cases.h"
#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"

namespace skinserve::testing {

struct QuantizedCase {
  uint32_t vertices;
  uint32_t influences;
  uint32_t joints;
  bool normals;
  RestEncoding encoding;
};

// A synthetic mesh moved off the origin by a seed-dependent amount, so the box's offset
// matters.
MeshArrays RandomQuantizedCaseMesh(const QuantizedCase& c, uint64_t seed);

// max |p| * max row sum of |M| + max |t| over the frame, times 1e-5 (+ 1e-5): the float32
// term of the tolerance (as CompareWithReference).
double FloatTolerance(std::span<const float> palette, const MeshArrays& a);

struct QuantizedErrors {
  double dequantized_position = 0;  // against reference 1
  double dequantized_normal = 0;
  double over_bound = 0;  // against reference 2: the largest error / bound
  double relative_to_extent = 0;
};

// The errors of one frame (`normals` empty: positions only); NaN counts as 1e30.
QuantizedErrors CheckQuantized(const Mesh& mesh, const MeshArrays& original,
                               std::span<const float> palette, std::span<const float> positions,
                               std::span<const float> normals);

// The stream's tangents: a synthetic mesh of c's shape with normals and tangents, stored as
// `encoding`, skinned by `backend` (positions, normals and tangents) and expected within
// CompareWithReference's tolerance of the float64 reference on the floats the integers
// decode to (ExpectFrameMatchesReference: tangents' xyz 1e-5, w exact), naming `what`.
void ExpectQuantizedTangentsMatchReference(Backend& backend, const MeshCase& c,
                                           RestEncoding encoding, uint64_t seed,
                                           const std::string& what);

}  // namespace skinserve::testing
