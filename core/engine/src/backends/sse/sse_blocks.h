// The block walk shared by the SSE kernels (linear and dual quaternion): vertices [first,
// last) in blocks of four, the last 1..3 vertices as a full block on a local copy padded by
// repeating the last vertex, so there is one code path and nothing is read or written out
// of bounds.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"

namespace skinserve::sse {

// skin_four(positions, normals, tangents, joints, weights, out_positions, out_normals,
// out_tangents) skins four vertices of `mesh` into `frame`'s outputs; normals and
// out_normals are null when !Normals, tangents and out_tangents when !Tangents (tangents
// come with normals only).
template <int B, bool Normals, bool Tangents, typename SkinFour>
inline void ForEachBlockOfFour(const Mesh& mesh, const SkinFrame& frame, std::size_t first,
                               std::size_t last, const SkinFour& skin_four) {
  const float* positions = RestPositions(mesh, frame);
  static_assert(Normals || !Tangents, "tangents come with normals");
  const float* normals = Normals ? RestNormals(mesh, frame) : nullptr;
  const float* tangents = Tangents ? RestTangents(mesh, frame) : nullptr;
  const uint16_t* joints = mesh.joints().data();
  const float* weights = mesh.weights().data();
  float* out_p = frame.positions.data();
  float* out_n = Normals ? frame.normals.data() : nullptr;
  float* out_t = Tangents ? frame.tangents.data() : nullptr;
  const std::size_t r = frame.rest_first;  // the rest arrays' vertex 0
  std::size_t v = first;
  for (; v + 4 <= last; v += 4) {
    skin_four(positions + 3 * (v - r), Normals ? normals + 3 * (v - r) : nullptr,
              Tangents ? tangents + 4 * (v - r) : nullptr, joints + B * v, weights + B * v,
              out_p + 3 * v, Normals ? out_n + 3 * v : nullptr, Tangents ? out_t + 4 * v : nullptr);
  }
  if (v == last) return;
  float in_p[12], in_n[12] = {}, res_p[12], res_n[12], in_w[4 * B];
  float in_t[16] = {}, res_t[16];
  uint16_t in_j[4 * B];
  const std::size_t count = last - v;
  for (std::size_t k = 0; k < 4; ++k) {
    const std::size_t src = v + std::min(k, count - 1);
    std::copy_n(positions + 3 * (src - r), 3, in_p + 3 * k);
    if constexpr (Normals) std::copy_n(normals + 3 * (src - r), 3, in_n + 3 * k);
    if constexpr (Tangents) std::copy_n(tangents + 4 * (src - r), 4, in_t + 4 * k);
    std::copy_n(joints + B * src, B, in_j + B * k);
    std::copy_n(weights + B * src, B, in_w + B * k);
  }
  skin_four(in_p, in_n, in_t, in_j, in_w, res_p, res_n, res_t);
  std::copy_n(res_p, 3 * count, out_p + 3 * v);
  if constexpr (Normals) std::copy_n(res_n, 3 * count, out_n + 3 * v);
  if constexpr (Tangents) std::copy_n(res_t, 4 * count, out_t + 4 * v);
}

}  // namespace skinserve::sse
