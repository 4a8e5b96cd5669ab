// Encoding and decoding. The snorm16 hot loops live in vertex_encoding_kernels.cpp
// (Highway, dispatched to the CPU's best SIMD target); float16's loops are branch-free so
// that the auto-vectoriser takes them. A failed check only sets a flag in the fast path; a
// slow scan then finds the value and names its vertex.
#include "skinserve/encoding/vertex_encoding.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "vertex_encoding_kernels.h"

namespace skinserve {

static_assert(std::endian::native == std::endian::little, "the wire is little-endian");

namespace {

constexpr const char* kAxisNames[3] = {"x", "y", "z"};
constexpr const char* kMinFieldNames[3] = {"bounds.min_x", "bounds.min_y", "bounds.min_z"};
constexpr const char* kMaxFieldNames[3] = {"bounds.max_x", "bounds.max_y", "bounds.max_z"};
// 16-bit values at any alignment (the wire's bytes, e.g. a gRPC slice, carry no alignment
// guarantee), through memcpy: an under-aligned typedef is not honoured by every compiler.
template <typename T>
inline T Load16(const std::byte* p, std::size_t i) {
  T v;
  std::memcpy(&v, p + 2 * i, 2);
  return v;
}
template <typename T>
inline void Store16(std::byte* p, std::size_t i, T v) {
  std::memcpy(p + 2 * i, &v, 2);
}

// float -> binary16 bits for |value| < 65520 (finite), round to nearest even.
// F. Giesen's float_to_half_fast3_rtne, written branch-free: both paths are computed.
inline uint16_t HalfBitsOfFinite(float value) {
  constexpr uint32_t kDenormMagicBits = 126u << 23;  // 0.5f: its ulp is half's 2^-24
  const uint32_t bits = std::bit_cast<uint32_t>(value);
  const uint32_t sign = (bits >> 16) & 0x8000u;
  const uint32_t magnitude = bits & 0x7fffffffu;
  // Result subnormal or zero: adding 0.5 rounds the value to a multiple of 2^-24.
  const uint32_t subnormal = std::bit_cast<uint32_t>(std::bit_cast<float>(magnitude) +
                                                     std::bit_cast<float>(kDenormMagicBits)) -
                             kDenormMagicBits;
  // Normal: rebias the exponent, round the 13 dropped bits to nearest even.
  const uint32_t odd = (magnitude >> 13) & 1u;
  const uint32_t normal = (magnitude - ((127u - 15u) << 23) + 0xfffu + odd) >> 13;
  const uint32_t small = 0u - static_cast<uint32_t>(magnitude < (113u << 23));
  return static_cast<uint16_t>((subnormal & small) | (normal & ~small) | sign);
}

// binary16 bits -> float, exact, branch-free.
inline float FloatOfHalfBits(uint16_t half) {
  constexpr uint32_t kExponentMask = 0x7c00u << 13;
  const uint32_t shifted = (static_cast<uint32_t>(half) & 0x7fffu) << 13;
  const uint32_t exponent = shifted & kExponentMask;
  const uint32_t rebiased = shifted + ((127u - 15u) << 23);
  // Inf/NaN: move the exponent to float's all-ones.
  const uint32_t special = rebiased + ((128u - 16u) << 23);
  // Zero/subnormal: renormalise through a float subtraction (exact).
  const uint32_t tiny = std::bit_cast<uint32_t>(std::bit_cast<float>(rebiased + (1u << 23)) -
                                                std::bit_cast<float>(113u << 23));
  const uint32_t is_special = 0u - static_cast<uint32_t>(exponent == kExponentMask);
  const uint32_t is_tiny = 0u - static_cast<uint32_t>(exponent == 0);
  const uint32_t magnitude =
      (special & is_special) | (tiny & is_tiny) | (rebiased & ~(is_special | is_tiny));
  return std::bit_cast<float>(magnitude | (static_cast<uint32_t>(half) & 0x8000u) << 16);
}

Status WrongOutputSize(const char* field, VertexEncoding encoding, std::size_t values,
                       std::size_t bytes) {
  return InvalidArgument(fmt::format("{}: {} values of {} need {} bytes, the output holds {}",
                                     field, values, VertexEncodingName(encoding),
                                     values * EncodedBytesPerValue(encoding), bytes));
}

Status NotATriple(const char* field, std::size_t values) {
  return InvalidArgument(
      fmt::format("{}: {} values is not a whole number of x y z triples", field, values));
}

// Per axis: centre, and the scale value -> q (0 for an empty axis).
struct Snorm16Axes {
  float centre[3];
  float half_extent[3];
  float scale[3];
  bool finite_scale = true;  // false: some axis is too thin for a float scale
};

Snorm16Axes AxesOf(const Bounds& bounds) {
  Snorm16Axes axes;
  for (int a = 0; a < 3; ++a) {
    // Halve before adding: no overflow for boxes near +-FLT_MAX.
    axes.centre[a] = bounds.min[a] * 0.5f + bounds.max[a] * 0.5f;
    axes.half_extent[a] = bounds.max[a] * 0.5f - bounds.min[a] * 0.5f;
    const double scale =
        axes.half_extent[a] > 0 ? kSnorm16Max / static_cast<double>(axes.half_extent[a]) : 0.0;
    if (scale > std::numeric_limits<float>::max()) axes.finite_scale = false;
    axes.scale[a] = static_cast<float>(scale);
  }
  return axes;
}

Status PositionError(const char* what, std::size_t vertex, int axis, float value) {
  return InvalidArgument(
      fmt::format("positions[vertex {}][{}] = {} {}", vertex, kAxisNames[axis], value, what));
}

Status EncodeFloat16(const char* field, std::span<const float> values, std::span<std::byte> out,
                     std::size_t first_vertex) {
  const std::size_t n = values.size();
  const float* in = values.data();
  std::byte* o = out.data();
  uint32_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float v = in[i];
    bad |= !(std::fabs(v) <= kFloat16Max);  // NaN fails too
    Store16(o, i, HalfBitsOfFinite(v));
  }
  if (bad == 0) return Status::Ok();
  for (std::size_t i = 0; i < n; ++i) {
    if (std::fabs(in[i]) <= kFloat16Max) continue;
    const std::size_t vertex = first_vertex + i / 3;
    const char* axis = kAxisNames[i % 3];
    if (!std::isfinite(in[i])) {
      return InvalidArgument(
          fmt::format("{}[vertex {}][{}] = {} is not finite", field, vertex, axis, in[i]));
    }
    return InvalidArgument(fmt::format("{}[vertex {}][{}] = {} is beyond float16's range +-65504",
                                       field, vertex, axis, in[i]));
  }
  return Status::Ok();
}

// The fallback for boxes with an axis thinner than 32767 / FLT_MAX: the same formula in
// double, value by value.
void EncodeSnorm16PositionsInDouble(std::span<const float> positions, const Snorm16Axes& axes,
                                    std::span<std::byte> out) {
  std::byte* o = out.data();
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const int a = static_cast<int>(i % 3);
    const double h = axes.half_extent[a];
    const double t =
        h > 0 ? (positions[i] - static_cast<double>(axes.centre[a])) / h * kSnorm16Max : 0.0;
    Store16(o, i, static_cast<int16_t>(std::clamp(std::nearbyint(t), -32767.0, 32767.0)));
  }
}

Status EncodeSnorm16Positions(std::span<const float> positions, const Bounds& bounds,
                              std::span<std::byte> out, std::size_t first_vertex) {
  const std::size_t n = positions.size();
  const float* in = positions.data();
  const Snorm16Axes axes = AxesOf(bounds);
  bool inside;
  if (axes.finite_scale) {
    inside = encoding_kernels::EncodeSnorm16Positions(
        in, n, axes.centre, axes.scale, bounds.min.data(), bounds.max.data(), out.data());
  } else {
    inside = true;
    for (std::size_t i = 0; i < n; ++i) {
      inside = inside && in[i] >= bounds.min[i % 3] && in[i] <= bounds.max[i % 3];
    }
    if (inside) EncodeSnorm16PositionsInDouble(positions, axes, out);
  }
  if (inside) return Status::Ok();
  for (std::size_t i = 0; i < n; ++i) {
    const int a = static_cast<int>(i % 3);
    if (in[i] >= bounds.min[a] && in[i] <= bounds.max[a]) continue;
    if (!std::isfinite(in[i]))
      return PositionError("is not finite", first_vertex + i / 3, a, in[i]);
    return PositionError(
        fmt::format("is outside the box [{}, {}]", bounds.min[a], bounds.max[a]).c_str(),
        first_vertex + i / 3, a, in[i]);
  }
  return Internal("EncodeSnorm16Positions: a value failed the box check but none is outside");
}

Status EncodeSnorm16Normals(std::span<const float> normals, std::span<std::byte> out,
                            std::size_t first_vertex) {
  if (encoding_kernels::EncodeSnorm16Normals(normals.data(), normals.size(), out.data())) {
    return Status::Ok();
  }
  constexpr float kLimit = 32767.5f;  // |n * 32767| below this rounds into [-32767, 32767]
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const float n = normals[i];
    if (std::fabs(n * static_cast<float>(kSnorm16Max)) < kLimit) continue;
    return InvalidArgument(fmt::format("normals[vertex {}][{}] = {} is {}", first_vertex + i / 3,
                                       kAxisNames[i % 3], n,
                                       std::isfinite(n) ? "outside [-1, 1]" : "not finite"));
  }
  return Internal("EncodeSnorm16Normals: a value failed the range check but none is outside");
}

Status CheckDecodeLength(const char* field, VertexEncoding encoding,
                         std::span<const std::byte> bytes, std::size_t values) {
  const std::size_t expected = values * EncodedBytesPerValue(encoding);
  if (bytes.size() == expected) return Status::Ok();
  return InvalidArgument(fmt::format("{}: {} bytes, expected {} ({} values of {})", field,
                                     bytes.size(), expected, values, VertexEncodingName(encoding)));
}

void DecodeFloat16(std::span<const std::byte> bytes, std::span<float> out) {
  const std::byte* in = bytes.data();
  float* o = out.data();
  for (std::size_t i = 0; i < out.size(); ++i) o[i] = FloatOfHalfBits(Load16<uint16_t>(in, i));
}

// ---- each encoding's own functions -----------------------------------------------------

Status EncodeFloat32(std::span<const float> values, bool, const Bounds&, std::span<std::byte> out,
                     std::size_t) {
  if (!out.empty()) std::memcpy(out.data(), values.data(), out.size());
  return Status::Ok();
}

Status DecodeFloat32(std::span<const std::byte> bytes, bool, const Bounds&, std::span<float> out) {
  if (!bytes.empty()) std::memcpy(out.data(), bytes.data(), bytes.size());
  return Status::Ok();
}

double Float32Error(bool, const Bounds&, int, double) { return 0.0; }

Status EncodeHalf(std::span<const float> values, bool normals, const Bounds&,
                  std::span<std::byte> out, std::size_t first_vertex) {
  return EncodeFloat16(normals ? "normals" : "positions", values, out, first_vertex);
}

Status DecodeHalf(std::span<const std::byte> bytes, bool, const Bounds&, std::span<float> out) {
  DecodeFloat16(bytes, out);
  return Status::Ok();
}

double HalfError(bool, const Bounds&, int, double x) {
  return std::max(std::fabs(x) * 0x1p-11, 0x1p-25);
}

Status EncodeSnorm16(std::span<const float> values, bool normals, const Bounds& bounds,
                     std::span<std::byte> out, std::size_t first_vertex) {
  if (normals) return EncodeSnorm16Normals(values, out, first_vertex);
  if (Status s = ValidateBounds(bounds); !s.ok()) return s;
  return EncodeSnorm16Positions(values, bounds, out, first_vertex);
}

Status DecodeSnorm16(std::span<const std::byte> bytes, bool normals, const Bounds& bounds,
                     std::span<float> out) {
  if (normals) {
    encoding_kernels::DecodeSnorm16Normals(bytes.data(), out.size(), out.data());
    return Status::Ok();
  }
  if (out.size() % 3 != 0) return NotATriple("positions", out.size());
  if (Status s = ValidateBounds(bounds); !s.ok()) return s;
  const Snorm16Axes axes = AxesOf(bounds);
  encoding_kernels::DecodeSnorm16Positions(bytes.data(), out.size(), axes.centre, axes.half_extent,
                                           out.data());
  return Status::Ok();
}

double Snorm16Error(bool normals, const Bounds& bounds, int axis, double) {
  if (normals) return 1.0 / 65534.0 + 0x1p-24;
  const double lo = bounds.min[axis];
  const double hi = bounds.max[axis];
  const double magnitude = std::max({std::fabs(lo), std::fabs(hi), 0x1p-126});
  return (hi - lo) / 131068.0 + 0x1p-20 * magnitude;
}

// The encodings, in the order of their values (skinserve.v1.Encoding).
constexpr EncodingDescription kEncodings[] = {
    {VertexEncoding::kFloat32, "float32", 4, false, &EncodeFloat32, &DecodeFloat32, &Float32Error},
    {VertexEncoding::kFloat16, "float16", 2, false, &EncodeHalf, &DecodeHalf, &HalfError},
    {VertexEncoding::kSnorm16, "snorm16", 2, true, &EncodeSnorm16, &DecodeSnorm16, &Snorm16Error},
};

const EncodingDescription* Find(VertexEncoding encoding) {
  const auto index = static_cast<std::size_t>(encoding);
  return index < std::size(kEncodings) ? &kEncodings[index] : nullptr;
}

Status Unknown(VertexEncoding encoding) {
  return InvalidArgument(fmt::format("encoding {} is unknown", static_cast<int>(encoding)));
}

Status Encode(const char* field, bool normals, VertexEncoding encoding,
              std::span<const float> values, const Bounds& bounds, std::span<std::byte> out,
              std::size_t first_vertex) {
  const EncodingDescription* e = Find(encoding);
  if (e == nullptr) return Unknown(encoding);
  if (values.size() % 3 != 0) return NotATriple(field, values.size());
  if (out.size() != values.size() * e->bytes_per_value) {
    return WrongOutputSize(field, encoding, values.size(), out.size());
  }
  return e->encode(values, normals, bounds, out, first_vertex);
}

Status Decode(const char* field, bool normals, VertexEncoding encoding,
              std::span<const std::byte> bytes, const Bounds& bounds, std::span<float> out) {
  const EncodingDescription* e = Find(encoding);
  if (e == nullptr) return Unknown(encoding);
  if (Status s = CheckDecodeLength(field, encoding, bytes, out.size()); !s.ok()) return s;
  return e->decode(bytes, normals, bounds, out);
}

}  // namespace

std::span<const EncodingDescription> Encodings() { return kEncodings; }

const EncodingDescription* DescribeEncoding(VertexEncoding encoding) { return Find(encoding); }

const char* VertexEncodingName(VertexEncoding encoding) {
  const EncodingDescription* e = Find(encoding);
  return e != nullptr ? e->name : "unknown";
}

std::optional<VertexEncoding> ParseVertexEncoding(std::string_view name) {
  for (const EncodingDescription& e : kEncodings) {
    if (name == e.name) return e.id;
  }
  return std::nullopt;
}

std::size_t EncodedBytesPerValue(VertexEncoding encoding) {
  const EncodingDescription* e = Find(encoding);
  return e != nullptr ? e->bytes_per_value : 4;
}

std::size_t EncodedBytes(VertexEncoding encoding, std::size_t vertex_count) {
  return vertex_count * kValuesPerVertex * EncodedBytesPerValue(encoding);
}

Result<Bounds> ComputeBounds(std::span<const float> positions, std::size_t first_vertex) {
  const std::size_t n = positions.size();
  if (n % 3 != 0) return NotATriple("positions", n);
  Bounds bounds;
  if (n == 0) return bounds;
  if (encoding_kernels::Bounds(positions.data(), n, bounds.min.data(), bounds.max.data())) {
    return bounds;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(positions[i])) {
      return PositionError("is not finite", first_vertex + i / 3, static_cast<int>(i % 3),
                           positions[i]);
    }
  }
  return Internal("ComputeBounds: a value failed the finiteness check but all are finite");
}

Status ValidateBounds(const Bounds& bounds) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(bounds.min[a])) {
      return InvalidArgument(
          fmt::format("{} = {} is not finite", kMinFieldNames[a], bounds.min[a]));
    }
    if (!std::isfinite(bounds.max[a])) {
      return InvalidArgument(
          fmt::format("{} = {} is not finite", kMaxFieldNames[a], bounds.max[a]));
    }
    if (bounds.min[a] > bounds.max[a]) {
      return InvalidArgument(fmt::format("{} = {} is below {} = {}", kMaxFieldNames[a],
                                         bounds.max[a], kMinFieldNames[a], bounds.min[a]));
    }
  }
  return Status::Ok();
}

Status EncodePositions(VertexEncoding encoding, std::span<const float> positions,
                       const Bounds& bounds, std::span<std::byte> out, std::size_t first_vertex) {
  return Encode("positions", false, encoding, positions, bounds, out, first_vertex);
}

Status EncodeNormals(VertexEncoding encoding, std::span<const float> normals,
                     std::span<std::byte> out, std::size_t first_vertex) {
  return Encode("normals", true, encoding, normals, Bounds{}, out, first_vertex);
}

Status DecodePositions(VertexEncoding encoding, std::span<const std::byte> bytes,
                       const Bounds& bounds, std::span<float> out) {
  return Decode("positions", false, encoding, bytes, bounds, out);
}

Status DecodeNormals(VertexEncoding encoding, std::span<const std::byte> bytes,
                     std::span<float> out) {
  return Decode("normals", true, encoding, bytes, Bounds{}, out);
}

std::size_t EncodedTangentBytes(VertexEncoding encoding, std::size_t vertex_count) {
  return vertex_count * kValuesPerTangent * EncodedBytesPerValue(encoding);
}

Status EncodeTangents(VertexEncoding encoding, std::span<const float> tangents,
                      std::span<std::byte> out, std::size_t first_vertex) {
  const EncodingDescription* e = Find(encoding);
  if (e == nullptr) return Unknown(encoding);
  if (tangents.size() % kValuesPerTangent != 0 ||
      out.size() != tangents.size() * e->bytes_per_value) {
    return InvalidArgument(fmt::format(
        "tangents: {} values into {} bytes of {}; expected 4 values a vertex, {} bytes each",
        tangents.size(), out.size(), e->name, e->bytes_per_value));
  }
  // The encoders' own errors count triples; a failing tangent is named here instead.
  if (e->encode(tangents, /*normals=*/true, Bounds{}, out, 0).ok()) return Status::Ok();
  const bool half = encoding == VertexEncoding::kFloat16;
  constexpr char kTangentAxes[] = "xyzw";
  for (std::size_t i = 0; i < tangents.size(); ++i) {
    const float t = tangents[i];
    // The encoders' limits: half's largest finite value; snorm16's [-1, 1] with rounding.
    if (half ? std::fabs(t) <= kFloat16Max : std::fabs(t * kSnorm16Max) < 32767.5f) continue;
    return InvalidArgument(fmt::format("tangents[vertex {}][{}] = {} is {}",
                                       first_vertex + i / kValuesPerTangent,
                                       kTangentAxes[i % kValuesPerTangent], t,
                                       !std::isfinite(t) ? "not finite"
                                       : half            ? "beyond float16's range +-65504"
                                                         : "outside [-1, 1]"));
  }
  return Internal("EncodeTangents: a value failed but none is out of range");
}

Status DecodeTangents(VertexEncoding encoding, std::span<const std::byte> bytes,
                      std::span<float> out) {
  const EncodingDescription* e = Find(encoding);
  if (e == nullptr) return Unknown(encoding);
  if (Status s = CheckDecodeLength("tangents", encoding, bytes, out.size()); !s.ok()) return s;
  return e->decode(bytes, /*normals=*/true, Bounds{}, out);
}

double PositionEncodingError(VertexEncoding encoding, const Bounds& bounds, int axis, double x) {
  const EncodingDescription* e = Find(encoding);
  return e != nullptr ? e->error(false, bounds, axis, x) : 0.0;
}

double NormalEncodingError(VertexEncoding encoding, double n) {
  const EncodingDescription* e = Find(encoding);
  return e != nullptr ? e->error(true, Bounds{}, 0, n) : 0.0;
}

uint16_t FloatToHalf(float value) {
  const uint32_t bits = std::bit_cast<uint32_t>(value);
  const uint32_t magnitude = bits & 0x7fffffffu;
  if (magnitude >= (143u << 23)) {  // >= 65536: infinity, or NaN (kept quiet)
    const uint32_t sign = (bits >> 16) & 0x8000u;
    return static_cast<uint16_t>(sign | (magnitude > 0x7f800000u ? 0x7e00u : 0x7c00u));
  }
  return HalfBitsOfFinite(value);
}

float HalfToFloat(uint16_t half) { return FloatOfHalfBits(half); }

}  // namespace skinserve
