// The float64 morph reference: every active target's deltas added to a dense copy of the
// rest arrays, target by target, as plainly as possible. Shares no code with the engine's
// morph stage (chunked, sparse cursors, float).
#include <algorithm>
#include <cmath>

#include "skinserve/reference/reference.h"

namespace skinserve {

ReferenceFrame ReferenceMorph(const Mesh& mesh, std::span<const MorphWeight> morph) {
  ReferenceFrame rest;
  rest.positions.assign(mesh.positions().begin(), mesh.positions().end());
  rest.normals.assign(mesh.normals().begin(), mesh.normals().end());
  rest.tangents.assign(mesh.tangents().begin(), mesh.tangents().end());
  for (const MorphWeight& w : morph) {
    const uint32_t first = mesh.morph_offsets()[w.target];
    const uint32_t last = mesh.morph_offsets()[w.target + 1];
    for (uint32_t k = first; k < last; ++k) {
      const std::size_t v = mesh.morph_indices()[k];
      for (int a = 0; a < 3; ++a) {
        rest.positions[3 * v + a] += double{w.weight} * mesh.morph_position_deltas()[3 * k + a];
        if (mesh.has_morph_normals() && !rest.normals.empty()) {
          rest.normals[3 * v + a] += double{w.weight} * mesh.morph_normal_deltas()[3 * k + a];
        }
        if (mesh.has_morph_tangents()) {  // xyz only: w is the handedness
          rest.tangents[4 * v + a] += double{w.weight} * mesh.morph_tangent_deltas()[3 * k + a];
        }
      }
    }
  }
  return rest;
}

MorphMagnitudes ReferenceMorphMagnitudes(const Mesh& mesh, std::span<const MorphWeight> morph) {
  MorphMagnitudes m;
  m.positions.resize(mesh.positions().size());
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    m.positions[i] = std::fabs(double{mesh.positions()[i]});
  }
  std::vector<double> normal_terms(mesh.vertex_count(), 0.0);
  std::vector<double> tangent_terms(mesh.vertex_count(), 0.0);
  for (const MorphWeight& w : morph) {
    const uint32_t first = mesh.morph_offsets()[w.target];
    const uint32_t last = mesh.morph_offsets()[w.target + 1];
    for (uint32_t k = first; k < last; ++k) {
      const std::size_t v = mesh.morph_indices()[k];
      for (int a = 0; a < 3; ++a) {
        m.positions[3 * v + a] +=
            std::fabs(double{w.weight} * mesh.morph_position_deltas()[3 * k + a]);
      }
      if (mesh.has_morph_normals()) {
        const float* dn = &mesh.morph_normal_deltas()[3 * k];
        normal_terms[v] +=
            std::fabs(double{w.weight}) *
            std::sqrt(double{dn[0]} * dn[0] + double{dn[1]} * dn[1] + double{dn[2]} * dn[2]);
      }
      if (mesh.has_morph_tangents()) {
        const float* dt = &mesh.morph_tangent_deltas()[3 * k];
        tangent_terms[v] +=
            std::fabs(double{w.weight}) *
            std::sqrt(double{dt[0]} * dt[0] + double{dt[1]} * dt[1] + double{dt[2]} * dt[2]);
      }
    }
  }
  if (mesh.has_normals()) {
    const ReferenceFrame rest = ReferenceMorph(mesh, morph);
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const float* n = &mesh.normals()[3 * v];
      const double* r = &rest.normals[3 * v];
      const double length =
          std::sqrt(double{n[0]} * n[0] + double{n[1]} * n[1] + double{n[2]} * n[2]);
      const double morphed = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      m.normal_magnification =
          std::max(m.normal_magnification, (length + normal_terms[v]) / morphed);
    }
  }
  if (mesh.has_tangents()) {
    const ReferenceFrame rest = ReferenceMorph(mesh, morph);
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      const float* t = &mesh.tangents()[4 * v];
      const double* r = &rest.tangents[4 * v];
      const double length =
          std::sqrt(double{t[0]} * t[0] + double{t[1]} * t[1] + double{t[2]} * t[2]);
      const double morphed = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      m.tangent_magnification =
          std::max(m.tangent_magnification, (length + tangent_terms[v]) / morphed);
    }
  }
  return m;
}

}  // namespace skinserve
