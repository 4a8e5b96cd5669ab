// Vertex encodings of a frame's answer (skinserve.v1.Encoding): float32 as the backend
// computed it, IEEE binary16, or snorm16 quantized to the instance's axis-aligned box.
// Server and client share this code: the server encodes into the response's bytes, the
// client decodes into caller-provided floats. Every function writes into memory the
// caller owns and allocates nothing on success.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "skinserve/model/status.h"

namespace skinserve {

// Values match skinserve.v1.Encoding.
enum class VertexEncoding : uint8_t { kFloat32 = 0, kFloat16 = 1, kSnorm16 = 2 };

inline constexpr std::size_t kValuesPerVertex = 3;
// float16's largest finite value; beyond it a value fails the frame.
inline constexpr float kFloat16Max = 65504.0f;
inline constexpr int32_t kSnorm16Max = 32767;

struct Bounds;

// An encoding, described once: its name, its size, its side data, its kernels and the error
// it states. Adding an encoding is a row of the table (vertex_encoding.cpp), its kernels,
// and its value in skinserve.v1.Encoding; everything below and the wire read the table.
struct EncodingDescription {
  VertexEncoding id;
  const char* name;             // as on the command line and in reports
  std::size_t bytes_per_value;  // per x, y or z
  bool quantized_to_box;        // each instance's Bounds travels with its values
  // x y z triples into exactly bytes_per_value * values.size() bytes; `normals` picks the
  // normals' rule; errors name the vertex (counted from first_vertex).
  Status (*encode)(std::span<const float> values, bool normals, const Bounds& bounds,
                   std::span<std::byte> out, std::size_t first_vertex);
  Status (*decode)(std::span<const std::byte> bytes, bool normals, const Bounds& bounds,
                   std::span<float> out);
  // The most a decoded value may differ from the float32 it encoded (axis: of `bounds`).
  double (*error)(bool normals, const Bounds& bounds, int axis, double value);
};

// Every encoding, in the order of their values.
std::span<const EncodingDescription> Encodings();
// Null for a value no encoding has.
const EncodingDescription* DescribeEncoding(VertexEncoding encoding);
// Whether each instance's box travels with its values (false for unknown values).
inline bool QuantizedToBox(VertexEncoding encoding) {
  const EncodingDescription* e = DescribeEncoding(encoding);
  return e != nullptr && e->quantized_to_box;
}

// "float32", "float16", "snorm16".
const char* VertexEncodingName(VertexEncoding encoding);
std::optional<VertexEncoding> ParseVertexEncoding(std::string_view name);

// Bytes a value takes (4 or 2), and the bytes of `vertex_count` x y z triples.
std::size_t EncodedBytesPerValue(VertexEncoding encoding);
std::size_t EncodedBytes(VertexEncoding encoding, std::size_t vertex_count);

// An axis-aligned box, per axis x y z.
struct Bounds {
  std::array<float, 3> min{};
  std::array<float, 3> max{};
  friend bool operator==(const Bounds&, const Bounds&) = default;
};

// The box of x y z triples (the whole instance, not one part of it): every value must
// be finite, else INVALID_ARGUMENT naming the vertex (counted from `first_vertex`). An
// empty span gives the zero box.
Result<Bounds> ComputeBounds(std::span<const float> positions, std::size_t first_vertex = 0);

// A box a client may decode with: finite, min <= max per axis; else INVALID_ARGUMENT
// naming the field (e.g. "bounds.max_y").
Status ValidateBounds(const Bounds& bounds);

// Encodes x y z triples into `out` (exactly EncodedBytes(encoding, positions.size() / 3)
// bytes, little-endian). float32: the bytes as they are. float16: round to nearest even;
// a value that is not finite or beyond +-65504 is INVALID_ARGUMENT naming the vertex
// (counted from `first_vertex`). snorm16: per axis c = (min + max) / 2, h = (max - min) / 2,
// q = round((x - c) / h * 32767), h = 0 giving q = 0; `bounds` must contain every value,
// else INVALID_ARGUMENT naming the vertex. On error `out` holds garbage.
Status EncodePositions(VertexEncoding encoding, std::span<const float> positions,
                       const Bounds& bounds, std::span<std::byte> out,
                       std::size_t first_vertex = 0);

// Normals (unit vectors): float32 and float16 as positions; snorm16 q = round(n * 32767),
// a component outside [-1, 1] (beyond rounding) or not finite is INVALID_ARGUMENT.
Status EncodeNormals(VertexEncoding encoding, std::span<const float> normals,
                     std::span<std::byte> out, std::size_t first_vertex = 0);

// Decodes `bytes` into `out` (x y z triples); `bytes` must hold exactly
// EncodedBytesPerValue(encoding) * out.size() bytes, else INVALID_ARGUMENT naming the field
// ("positions" / "normals"), both lengths and the encoding. snorm16 positions decode as
// x' = c + (q / 32767) * h with `bounds` checked by ValidateBounds first.
Status DecodePositions(VertexEncoding encoding, std::span<const std::byte> bytes,
                       const Bounds& bounds, std::span<float> out);
Status DecodeNormals(VertexEncoding encoding, std::span<const std::byte> bytes,
                     std::span<float> out);

// Tangents, x y z w per vertex (SkinRequest.want_tangents): every value encodes as a
// normal's (x y z unit, w exactly +1 or -1, which float16 and snorm16 hold exactly);
// errors name "tangents[vertex v][axis]". The byte count is EncodedTangentBytes.
inline constexpr std::size_t kValuesPerTangent = 4;
std::size_t EncodedTangentBytes(VertexEncoding encoding, std::size_t vertex_count);
Status EncodeTangents(VertexEncoding encoding, std::span<const float> tangents,
                      std::span<std::byte> out, std::size_t first_vertex = 0);
Status DecodeTangents(VertexEncoding encoding, std::span<const std::byte> bytes,
                      std::span<float> out);

// What an encoding may add to the error of one decoded value, beyond the float32 result:
//   float32: 0.
//   float16: max(|x| * 2^-11, 2^-25) (half an ulp; 2^-25 below half's normal range).
//   snorm16 positions, per axis: (max - min) / 131068 (half a step)
//            + 2^-20 * max(|min|, |max|, 2^-126) (float32 rounding of encode and decode).
//   snorm16 normals: 1 / 65534 + 2^-24.
double PositionEncodingError(VertexEncoding encoding, const Bounds& bounds, int axis, double x);
double NormalEncodingError(VertexEncoding encoding, double n);

// Bit-exact IEEE 754 binary16 conversions (round to nearest even; NaN stays NaN, infinity
// stays infinity, no exceptions). Portable: x86-64's baseline has no F16C.
uint16_t FloatToHalf(float value);
float HalfToFloat(uint16_t half);

}  // namespace skinserve
