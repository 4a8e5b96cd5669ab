// The scalar dual-quaternion skinning loop shared by `serial` and `openmp`, specialised
// per influence count B like their linear loop (scalar_skinning.h). Per vertex: blend the
// B unit dual quaternions of the frame's DualQuaternionPalette, each one's sign chosen
// against the first influence (q and -q are the same rotation; blending across the two
// hemispheres would take the long way round), normalise, transform the position; the
// normal and the tangent's xyz are rotated by the blended rotation (the tangent's w kept).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "backends/common/dual_quaternion_palette.h"
#include "backends/common/influence_dispatch.h"
#include "skinserve/engine/backend.h"

namespace skinserve::scalar {

// Skins vertices [first, last) of `mesh` into `frame` with B influences per vertex.
template <int B>
void SkinDualQuaternionRange(const Mesh& mesh, const DualQuaternionPalette& palette,
                             const SkinFrame& frame, std::size_t first, std::size_t last) {
  const float* quaternions = palette.joint(0);
  const float* positions = RestPositions(mesh, frame);
  const float* normals = RestNormals(mesh, frame);
  const float* tangents = RestTangents(mesh, frame);
  const uint16_t* joints = mesh.joints().data();
  const float* weights = mesh.weights().data();
  float* out_p = frame.positions.data();
  float* out_n = frame.normals.empty() ? nullptr : frame.normals.data();
  float* out_t = frame.tangents.empty() ? nullptr : frame.tangents.data();
  constexpr std::size_t kStride = DualQuaternionPalette::kFloatsPerJoint;
  const std::size_t r = frame.rest_first;  // the rest arrays' vertex 0
  for (std::size_t v = first; v < last; ++v) {
    const float* q0 = quaternions + kStride * joints[v * B];
    float b[8];
    {
      const float w = weights[v * B];
      for (int e = 0; e < 8; ++e) b[e] = w * q0[e];
    }
    for (int i = 1; i < B; ++i) {
      const float* q = quaternions + kStride * joints[v * B + i];
      const float dot = q0[0] * q[0] + q0[1] * q[1] + q0[2] * q[2] + q0[3] * q[3];
      const float w = dot < 0 ? -weights[v * B + i] : weights[v * B + i];
      for (int e = 0; e < 8; ++e) b[e] += w * q[e];
    }
    const float inverse = 1.0f / std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2] + b[3] * b[3]);
    const float rx = b[0] * inverse, ry = b[1] * inverse, rz = b[2] * inverse, rw = b[3] * inverse;
    const float dx = b[4] * inverse, dy = b[5] * inverse, dz = b[6] * inverse, dw = b[7] * inverse;
    // Translation t = 2 (rw d - dw r + r x d) (vector parts), rotation p + 2 r x (r x p + rw p).
    const float tx = 2 * (rw * dx - dw * rx + (ry * dz - rz * dy));
    const float ty = 2 * (rw * dy - dw * ry + (rz * dx - rx * dz));
    const float tz = 2 * (rw * dz - dw * rz + (rx * dy - ry * dx));
    // p + 2 r x (r x p + rw p): the rotation part, for positions, normals and tangents.
    const auto rotate = [&](const float* in, float* out) {
      const float x = in[0], y = in[1], z = in[2];
      const float cx = ry * z - rz * y + rw * x, cy = rz * x - rx * z + rw * y,
                  cz = rx * y - ry * x + rw * z;
      out[0] = x + 2 * (ry * cz - rz * cy);
      out[1] = y + 2 * (rz * cx - rx * cz);
      out[2] = z + 2 * (rx * cy - ry * cx);
    };
    rotate(positions + 3 * (v - r), out_p + 3 * v);
    out_p[3 * v] += tx, out_p[3 * v + 1] += ty, out_p[3 * v + 2] += tz;
    // Normals and tangents come out unit, as linear blending's: the rotation keeps a
    // length, and a morphed normal's is not 1.
    const auto normalize = [](float* out) {
      const float inv = 1.0f / std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
      out[0] *= inv, out[1] *= inv, out[2] *= inv;
    };
    if (out_n != nullptr) {
      rotate(normals + 3 * (v - r), out_n + 3 * v);
      normalize(out_n + 3 * v);
    }
    if (out_t != nullptr) {
      rotate(tangents + 4 * (v - r), out_t + 4 * v);
      normalize(out_t + 4 * v);
      out_t[4 * v + 3] = tangents[4 * (v - r) + 3];
    }
  }
}

// The dual-quaternion kernel of CpuBackend (cpu_backend.h).
struct ScalarDualQuaternionKernel {
  using FramePalette = DualQuaternionPalette;
  static void SkinRange(const Mesh& mesh, const FramePalette& palette, const SkinFrame& frame,
                        std::size_t first, std::size_t last) {
    WithInfluences(mesh.influences(), [&](auto b) {
      SkinDualQuaternionRange<decltype(b)::value>(mesh, palette, frame, first, last);
    });
  }
};

}  // namespace skinserve::scalar
