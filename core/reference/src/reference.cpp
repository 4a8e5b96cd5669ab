#include "skinserve/reference/reference.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "skinserve/model/palette.h"

namespace skinserve {

namespace {

// Equations 3 and 4 in double, whatever the palette's type.
template <typename Real>
ReferenceFrame SkinInDouble(const Mesh& mesh, std::span<const Real> palette,
                            std::span<const MorphWeight> morph) {
  const ReferenceFrame rest = ReferenceMorph(mesh, morph);
  const std::size_t v_count = mesh.vertex_count();
  const std::size_t b = mesh.influences();
  ReferenceFrame out;
  out.positions.resize(3 * v_count);
  if (mesh.has_normals()) out.normals.resize(3 * v_count);
  if (mesh.has_tangents()) out.tangents.resize(4 * v_count);
  for (std::size_t v = 0; v < v_count; ++v) {
    // Equation 3: blend the B joint matrices with the vertex's weights.
    double m[12] = {};
    for (std::size_t i = 0; i < b; ++i) {
      const double w = mesh.weights()[v * b + i];
      const Real* joint = &palette[kFloatsPerJoint * mesh.joints()[v * b + i]];
      for (int e = 0; e < 12; ++e) m[e] += w * joint[e];
    }
    // Equation 4: the affine transform of (x, y, z, 1).
    const double* p = &rest.positions[3 * v];
    for (int r = 0; r < 3; ++r) {
      out.positions[3 * v + r] =
          m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3];
    }
    if (mesh.has_normals()) {
      const double* n = &rest.normals[3 * v];
      double t[3];
      for (int r = 0; r < 3; ++r)
        t[r] = m[4 * r] * n[0] + m[4 * r + 1] * n[1] + m[4 * r + 2] * n[2];
      const double length = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
      for (int r = 0; r < 3; ++r) out.normals[3 * v + r] = t[r] / length;
    }
    if (mesh.has_tangents()) {  // as the normal; w, the handedness, as it is
      const double* rest_t = &rest.tangents[4 * v];
      double t[3];
      for (int r = 0; r < 3; ++r) {
        t[r] = m[4 * r] * rest_t[0] + m[4 * r + 1] * rest_t[1] + m[4 * r + 2] * rest_t[2];
      }
      const double length = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
      for (int r = 0; r < 3; ++r) out.tangents[4 * v + r] = t[r] / length;
      out.tangents[4 * v + 3] = rest_t[3];
    }
  }
  return out;
}

}  // namespace

ReferenceFrame ReferenceSkin(const Mesh& mesh, std::span<const float> palette,
                             std::span<const MorphWeight> morph) {
  return SkinInDouble(mesh, palette, morph);
}

ReferenceFrame ReferenceSkin(const Mesh& mesh, std::span<const double> palette,
                             std::span<const MorphWeight> morph) {
  return SkinInDouble(mesh, palette, morph);
}

Deviation CompareWithReference(const Mesh& mesh, std::span<const float> palette,
                               std::span<const float> positions, std::span<const float> normals,
                               SkinningMethod method, std::span<const MorphWeight> morph,
                               std::span<const float> tangents) {
  const ReferenceFrame ref = method == SkinningMethod::kDualQuaternion
                                 ? ReferenceSkinDualQuaternion(mesh, palette, morph)
                                 : ReferenceSkin(mesh, palette, morph);
  Deviation d;
  // S bounds |M p| for this frame: float32 rounding is relative to it, not to |p'|, which
  // may cancel to near zero. With morphs, p's terms: |rest| + sum |w delta| per coordinate.
  const MorphMagnitudes terms = ReferenceMorphMagnitudes(mesh, morph);
  double max_p = 0, max_row = 0, max_t = 0;
  for (double x : terms.positions) max_p = std::max(max_p, x);
  for (std::size_t j = 0; j < palette.size() / kFloatsPerJoint; ++j) {
    for (int r = 0; r < 3; ++r) {
      const float* row = &palette[kFloatsPerJoint * j + 4 * r];
      max_row = std::max(max_row, std::fabs(double{row[0]}) + std::fabs(double{row[1]}) +
                                      std::fabs(double{row[2]}));
      max_t = std::max(max_t, std::fabs(double{row[3]}));
    }
  }
  d.position_tolerance = 1e-5 * (1 + max_p * max_row + max_t);
  d.normal_tolerance = 1e-5 * terms.normal_magnification;
  d.tangent_tolerance = 1e-5 * terms.tangent_magnification;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  auto error = [](double a, double b) { return std::isnan(a) ? kInf : std::fabs(a - b); };
  double worst = -1;
  const std::size_t count = std::min(positions.size(), ref.positions.size());
  if (positions.size() != ref.positions.size()) d.max_position_error = kInf;
  for (std::size_t i = 0; i < count; ++i) {
    const double e = error(positions[i], ref.positions[i]);
    if (e > d.max_position_error) d.max_position_error = e;
    if (e / d.position_tolerance > worst) worst = e / d.position_tolerance, d.worst_vertex = i / 3;
  }
  if (!normals.empty()) {
    if (normals.size() != ref.normals.size()) d.max_normal_error = kInf;
    const std::size_t n = std::min(normals.size(), ref.normals.size());
    for (std::size_t i = 0; i < n; ++i) {
      const double e = error(normals[i], ref.normals[i]);
      if (e > d.max_normal_error) d.max_normal_error = e;
      if (e / d.normal_tolerance > worst) worst = e / d.normal_tolerance, d.worst_vertex = i / 3;
    }
  }
  if (!tangents.empty()) {
    if (tangents.size() != ref.tangents.size()) d.max_tangent_error = kInf;
    const std::size_t n = std::min(tangents.size(), ref.tangents.size());
    for (std::size_t i = 0; i < n; ++i) {
      const double e = error(tangents[i], ref.tangents[i]);
      if (e > d.max_tangent_error) d.max_tangent_error = e;
      if (e / d.tangent_tolerance > worst) worst = e / d.tangent_tolerance, d.worst_vertex = i / 4;
    }
  }
  return d;
}

}  // namespace skinserve
