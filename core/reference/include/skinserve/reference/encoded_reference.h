// Checks results that travelled in a compact encoding against the float64 reference: each
// value within the float32 tolerance of CompareWithReference plus the bound its encoding
// states (vertex_encoding.h).
#pragma once

#include <cstddef>
#include <span>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/skinning_method.h"

namespace skinserve {

struct EncodedDeviation {
  // The largest |decoded - reference| / (float32 tolerance + encoding bound) over every
  // value (infinite for NaN or a wrong length): within the bound while <= 1.
  double worst_position_ratio = 0;
  double worst_normal_ratio = 0;
  std::size_t worst_vertex = 0;
  double max_position_error = 0;  // max |decoded - reference|
  double max_normal_error = 0;
  bool within_tolerance() const { return worst_position_ratio <= 1 && worst_normal_ratio <= 1; }
};

// One instance's decoded positions (and normals, may be empty to skip them) in `encoding`,
// quantized to `bounds` for snorm16 (as the response carried it), against the reference of
// `method`, of the rest arrays morphed by `morph` (none: as they are).
EncodedDeviation CompareEncodedWithReference(const Mesh& mesh, std::span<const float> palette,
                                             VertexEncoding encoding, const Bounds& bounds,
                                             std::span<const float> positions,
                                             std::span<const float> normals,
                                             SkinningMethod method = SkinningMethod::kLinear,
                                             std::span<const MorphWeight> morph = {});

// How many of the decoded tangents' values (x y z w per vertex) lie outside the float32
// tolerance (1e-5) plus `encoding`'s unit-vector bound of the reference's (w, +1 or -1,
// must be exact); a wrong length counts every value.
std::size_t TangentValuesOutsideBound(VertexEncoding encoding, std::span<const float> decoded,
                                      std::span<const double> reference);

}  // namespace skinserve
