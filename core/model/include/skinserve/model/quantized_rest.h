// QuantizedRest: a mesh's rest stream in 16- and 8-bit integers, built once at upload when
// the client asks for it (RestEncoding), for the loops that read it directly (`simd`,
// `simd-openmp`): fewer bytes per vertex streamed per frame, where a frame is bound by
// memory bandwidth.
//
//  - positions: uint16 per axis in the mesh's box, x = offset + scale * q, scale =
//    extent / 65535 (rounded up, so the box is covered): error <= scale / 2 per axis.
//  - normals:   snorm16 of the unit direction, n = q / 32767: error <= 1 / 65534 per
//    component. snorm16 rather than 16-bit octahedral: the loop turns it into floats with
//    one conversion per component and no scale at all (normals are renormalised after
//    skinning), where octahedral needs a sign-dependent decode per vertex for 2 bytes less.
//  - tangents:  4 int16 per vertex: xyz as the normals (snorm16 of the unit direction), w
//               (the handedness, +1 or -1) as +-32767.
//  - weights:   the first B - 1 as unorm16 (kQuantized16) or unorm8 (kQuantized8Weights),
//    w = q / 65535 or q / 255; the last is 1 - their sum. Rounded to nearest, then lowered
//    where their sum would pass 1: error < 1 step per weight.
//  - joints:    uint8 when joint_count <= 256, else uint16.
// Streamed per vertex at B influences: 6 + B (or 2B) + (B - 1) * 2 (or 1) bytes in, plus
// 12 bytes of float32 positions out (6 + 12 more for normals, 8 + 16 for tangents): 28 (or
// 25) bytes at B = 4 against the float stream's 40.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "skinserve/model/aligned_buffer.h"

namespace skinserve {

enum class RestEncoding {
  kFloat32,            // the mesh's float arrays only (the default)
  kQuantized16,        // uint16 positions, snorm16 normals, unorm16 weights
  kQuantized8Weights,  // the same with unorm8 weights
};

std::string_view RestEncodingName(RestEncoding encoding);  // "float32", "quantized16", ...
std::optional<RestEncoding> ParseRestEncoding(std::string_view name);

// Steps of the integer weights: w = q / WeightSteps(encoding).
inline constexpr uint32_t kWeightSteps16 = 65535;
inline constexpr uint32_t kWeightSteps8 = 255;
inline constexpr float kNormalSteps = 32767.0f;
inline constexpr uint32_t kPositionSteps = 65535;

struct QuantizedRest {
  RestEncoding encoding = RestEncoding::kQuantized16;
  uint32_t influences = 0;
  float offset[3] = {};               // the box's low corner
  float scale[3] = {};                // one step per axis
  AlignedBuffer<uint16_t> positions;  // 3 per vertex
  AlignedBuffer<int16_t> normals;     // 3 per vertex, or empty
  AlignedBuffer<int16_t> tangents;    // 4 per vertex (w: +-32767), or empty
  AlignedBuffer<uint8_t> joints8;     // B per vertex when joint_count <= 256, else empty
  AlignedBuffer<uint16_t> joints16;   // B per vertex otherwise
  AlignedBuffer<uint8_t> weights8;    // B - 1 per vertex (kQuantized8Weights)
  AlignedBuffer<uint16_t> weights16;  // B - 1 per vertex (kQuantized16)

  uint64_t byte_size() const;
};

// Bytes one frame streams per vertex through memory: the rest stream in, float32 out.
double StreamedBytesPerVertex(RestEncoding encoding, uint32_t influences, uint32_t joint_count,
                              bool normals, bool tangents = false);

// Bytes QuantizedRest holds per vertex (the store's budget counts them beside the floats).
uint64_t QuantizedRestBytesPerVertex(RestEncoding encoding, uint64_t influences,
                                     uint64_t joint_count, bool has_normals,
                                     bool has_tangents = false);

// Quantizes validated arrays (weights summing to 1, normals and tangents non-zero, tangents'
// w +-1) and overwrites `positions`, `normals`, `tangents` and `weights` with the values the
// integers decode to, rounded to float32, so every backend skins the same mesh the quantized
// stream encodes.
QuantizedRest Quantize(RestEncoding encoding, uint32_t vertex_count, uint32_t influences,
                       uint32_t joint_count, std::span<float> positions, std::span<float> normals,
                       std::span<float> tangents, std::span<const uint16_t> joints,
                       std::span<float> weights);

}  // namespace skinserve
