// The leaner vertex stream the `simd` backends read, and the kernel Highway picks for
// this CPU. Positions, normals and tangents are the mesh's own arrays; joint indices shrink to
// 8 bits when the mesh has at most 256 joints, and of each vertex's B weights only the
// first B - 1 are stored: the mesh's weights sum to 1, so the kernel derives the last
// one (no weights at all for B = 1). At B = 4 a vertex streams 40 bytes instead of 48.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace skinserve::simd {

// Palette layout per joint: 16 floats, the four columns (m[0][c], m[1][c], m[2][c], 0),
// 64-byte aligned, so one joint is one 512-bit, two 256-bit or four 128-bit vectors.
inline constexpr std::size_t kFloatsPerJoint = 16;

struct VertexStream {
  uint32_t influences = 0;             // B, 1..8
  const float* positions = nullptr;    // 3 per vertex
  const float* normals = nullptr;      // 3 per vertex, or null
  const float* tangents = nullptr;     // 4 per vertex (x y z w), or null
  const uint8_t* joints8 = nullptr;    // B per vertex when joint_count <= 256, else null
  const uint16_t* joints16 = nullptr;  // B per vertex otherwise
  const float* weights = nullptr;      // B - 1 per vertex (null for B = 1)
};

// A mesh's quantized rest stream (skinserve/model/quantized_rest.h) as the kernel reads it.
// The box's offset and scale are folded into the frame's palette (columns x, y, z times
// the axis's scale; the fourth column plus the offset through the matrix), so a position
// costs the loop three integer-to-float conversions and nothing else; normals, skinned by
// the unscaled matrix, are divided by the scale per axis (normal_scale = 1 / scale) and
// renormalised as usual, which absorbs snorm16's 1 / 32767.
struct QuantizedStream {
  uint32_t influences = 0;              // B, 1..8
  const uint16_t* positions = nullptr;  // 3 per vertex
  const int16_t* normals = nullptr;     // 3 per vertex, or null
  const int16_t* tangents = nullptr;    // 4 per vertex (w +-32767), or null
  const uint8_t* joints8 = nullptr;     // B per vertex when joint_count <= 256, else null
  const uint16_t* joints16 = nullptr;   // B per vertex otherwise
  const uint8_t* weights8 = nullptr;    // B - 1 unorm8 per vertex, or null
  const uint16_t* weights16 = nullptr;  // B - 1 unorm16 per vertex, or null
  float normal_scale[3] = {1, 1, 1};
};

// Skins vertices [first, last): positions always, normals when out_normals is not null
// (the stream must have normals then), tangents (4 floats per vertex, w copied) when
// out_tangents is not null (normals too then). Writes exactly those vertices' outputs.
using SkinRangeFn = void (*)(const VertexStream& stream, const float* columns, float* out_positions,
                             float* out_normals, float* out_tangents, std::size_t first,
                             std::size_t last);

// The same from a quantized stream, with the palette's columns folded with its box
// (tangents' xyz divided by the scale as the normals are).
using SkinQuantizedRangeFn = void (*)(const QuantizedStream& stream, const float* columns,
                                      float* out_positions, float* out_normals, float* out_tangents,
                                      std::size_t first, std::size_t last);

// A frame's palette for the dual-quaternion kernel.
struct DualQuaternionFrame {
  // DualQuaternionPalette: 8 floats per joint; with a hemisphere table, 2 J records: the J
  // joints', then their negations.
  const float* quaternions = nullptr;
  // Null, or (8-bit joint streams only) J x J offsets into `quaternions`: hemisphere[i * J + j]
  // is where joint j's dual quaternion in joint i's hemisphere starts, 8 j when q_i . q_j >= 0,
  // else 8 (J + j), its negation (q and -q are the same rotation), so the kernel loads each
  // influence with its sign already chosen. Built once per frame when that is cheaper than a
  // dot product per vertex and influence.
  const uint16_t* hemisphere = nullptr;
  uint32_t joint_count = 0;
};

// The same for dual-quaternion skinning.
using SkinDualQuaternionRangeFn = void (*)(const VertexStream& stream,
                                           const DualQuaternionFrame& palette, float* out_positions,
                                           float* out_normals, float* out_tangents,
                                           std::size_t first, std::size_t last);

struct Kernel {
  SkinRangeFn skin_range = nullptr;
  SkinDualQuaternionRangeFn skin_dual_quaternion_range = nullptr;
  SkinQuantizedRangeFn skin_quantized_range = nullptr;
  const char* target = "";  // Highway's name of the target, e.g. "AVX3", "AVX2", "NEON"
  int lanes = 0;            // float lanes per vector the kernel uses
};

// Targets compiled into this binary that this CPU runs, best first (Highway's names).
std::vector<std::string> RunnableTargets();

// The kernel of the best runnable target no better than `max_target` (empty: the best).
// False, with `error` naming the runnable targets, when `max_target` is not one of them.
bool SelectKernel(const std::string& max_target, Kernel* kernel, std::string* error);

// Caps Highway's dispatch for every other dispatched loop of the process (the vertex
// encodings) at `max_target` (empty: the CPU's best); false as SelectKernel.
bool CapDispatch(const std::string& max_target, std::string* error);

}  // namespace skinserve::simd
