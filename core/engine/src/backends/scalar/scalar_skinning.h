// The scalar linear blend skinning loop shared by `serial` and `openmp`, specialised per
// influence count B at compile time (a template, where ozz-animation uses macros).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "backends/common/influence_dispatch.h"
#include "skinserve/engine/backend.h"

namespace skinserve::scalar {

// Skins vertices [first, last) of `mesh` into `frame` with B influences per vertex.
template <int B>
void SkinScalarRange(const Mesh& mesh, const float* palette, const SkinFrame& frame,
                     std::size_t first, std::size_t last) {
  const float* positions = RestPositions(mesh, frame);
  const float* normals = RestNormals(mesh, frame);
  const float* tangents = RestTangents(mesh, frame);
  const uint16_t* joints = mesh.joints().data();
  const float* weights = mesh.weights().data();
  float* out_p = frame.positions.data();
  float* out_n = frame.normals.empty() ? nullptr : frame.normals.data();
  float* out_t = frame.tangents.empty() ? nullptr : frame.tangents.data();
  const std::size_t r = frame.rest_first;  // the rest arrays' vertex 0
  for (std::size_t v = first; v < last; ++v) {
    // Equation 3: m = sum_i w_i * palette[d_i].
    float m[12];
    {
      const float w = weights[v * B];
      const float* j = palette + 12 * joints[v * B];
      for (int e = 0; e < 12; ++e) m[e] = w * j[e];
    }
    for (int i = 1; i < B; ++i) {
      const float w = weights[v * B + i];
      const float* j = palette + 12 * joints[v * B + i];
      for (int e = 0; e < 12; ++e) m[e] += w * j[e];
    }
    // Equation 4: p' = m (x, y, z, 1).
    const float* p = positions + 3 * (v - r);
    const float x = p[0], y = p[1], z = p[2];
    out_p[3 * v] = m[0] * x + m[1] * y + m[2] * z + m[3];
    out_p[3 * v + 1] = m[4] * x + m[5] * y + m[6] * z + m[7];
    out_p[3 * v + 2] = m[8] * x + m[9] * y + m[10] * z + m[11];
    if (out_n != nullptr) {
      const float* n = normals + 3 * (v - r);
      const float nx = n[0], ny = n[1], nz = n[2];
      const float tx = m[0] * nx + m[1] * ny + m[2] * nz;
      const float ty = m[4] * nx + m[5] * ny + m[6] * nz;
      const float tz = m[8] * nx + m[9] * ny + m[10] * nz;
      const float inv = 1.0f / std::sqrt(tx * tx + ty * ty + tz * tz);
      out_n[3 * v] = tx * inv;
      out_n[3 * v + 1] = ty * inv;
      out_n[3 * v + 2] = tz * inv;
    }
    if (out_t != nullptr) {  // the tangent's xyz as the normal, its w as it is
      const float* t = tangents + 4 * (v - r);
      const float sx = m[0] * t[0] + m[1] * t[1] + m[2] * t[2];
      const float sy = m[4] * t[0] + m[5] * t[1] + m[6] * t[2];
      const float sz = m[8] * t[0] + m[9] * t[1] + m[10] * t[2];
      const float inv = 1.0f / std::sqrt(sx * sx + sy * sy + sz * sz);
      out_t[4 * v] = sx * inv;
      out_t[4 * v + 1] = sy * inv;
      out_t[4 * v + 2] = sz * inv;
      out_t[4 * v + 3] = t[3];
    }
  }
}

// The kernel of CpuBackend (cpu_backend.h): the palette as it comes, SkinScalarRange<B>
// for the mesh's B (1..8).
struct ScalarKernel {
  using FramePalette = std::span<const float>;
  static void SkinRange(const Mesh& mesh, FramePalette palette, const SkinFrame& frame,
                        std::size_t first, std::size_t last) {
    WithInfluences(mesh.influences(), [&](auto b) {
      SkinScalarRange<decltype(b)::value>(mesh, palette.data(), frame, first, last);
    });
  }
};

}  // namespace skinserve::scalar
