#include "skinserve/reference/encoded_reference.h"

#include <cmath>
#include <limits>

#include "skinserve/reference/reference.h"

namespace skinserve {

EncodedDeviation CompareEncodedWithReference(const Mesh& mesh, std::span<const float> palette,
                                             VertexEncoding encoding, const Bounds& bounds,
                                             std::span<const float> positions,
                                             std::span<const float> normals, SkinningMethod method,
                                             std::span<const MorphWeight> morph) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // The float32 tolerances of this mesh and pose (the comparison itself is redone below).
  const Deviation float32 = CompareWithReference(mesh, palette, positions, normals, method, morph);
  const ReferenceFrame ref = method == SkinningMethod::kDualQuaternion
                                 ? ReferenceSkinDualQuaternion(mesh, palette, morph)
                                 : ReferenceSkin(mesh, palette, morph);
  EncodedDeviation d;
  double worst = -1;
  // The encoding rounds the float32 result, which lies within the tolerance of the
  // reference: its bound is taken at |reference| + tolerance.
  const auto check = [&](std::span<const float> got, const std::vector<double>& want,
                         double tolerance, bool is_position, double* max_error, double* ratio) {
    if (got.size() != want.size()) {
      *max_error = *ratio = kInf;
      return;
    }
    for (std::size_t i = 0; i < got.size(); ++i) {
      const double at = std::fabs(want[i]) + tolerance;
      const double bound =
          tolerance + (is_position ? PositionEncodingError(encoding, bounds, i % 3, at)
                                   : NormalEncodingError(encoding, at));
      const double e = std::isnan(got[i]) ? kInf : std::fabs(got[i] - want[i]);
      *max_error = std::max(*max_error, e);
      *ratio = std::max(*ratio, e / bound);
      if (e / bound > worst) worst = e / bound, d.worst_vertex = i / 3;
    }
  };
  check(positions, ref.positions, float32.position_tolerance, true, &d.max_position_error,
        &d.worst_position_ratio);
  if (!normals.empty()) {
    check(normals, ref.normals, float32.normal_tolerance, false, &d.max_normal_error,
          &d.worst_normal_ratio);
  }
  return d;
}

std::size_t TangentValuesOutsideBound(VertexEncoding encoding, std::span<const float> decoded,
                                      std::span<const double> reference) {
  if (decoded.size() != reference.size()) return std::max(decoded.size(), reference.size());
  std::size_t outside = 0;
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    const double r = reference[i];
    if (i % 4 == 3) {
      outside += decoded[i] != r;  // w is +1 or -1: every encoding holds it exactly
    } else {
      outside += !(std::fabs(decoded[i] - r) <= 1e-5 + NormalEncodingError(encoding, r));
    }
  }
  return outside;
}

}  // namespace skinserve
