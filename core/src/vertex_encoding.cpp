// Encoding and decoding loops. Each hot loop is branch-free over plain arrays so that the
// compiler vectorises it at the baseline ISA; a failed check is found again by a slow scan
// that names the vertex, so the fast path carries only a flag.
#include "skinserve/core/vertex_encoding.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

namespace skinserve {

static_assert(std::endian::native == std::endian::little, "the wire is little-endian");

namespace {

constexpr const char* kAxisNames[3] = {"x", "y", "z"};
constexpr const char* kMinFieldNames[3] = {"bounds.min_x", "bounds.min_y", "bounds.min_z"};
constexpr const char* kMaxFieldNames[3] = {"bounds.max_x", "bounds.max_y", "bounds.max_z"};
constexpr float kInvSnorm16Max = 1.0f / static_cast<float>(kSnorm16Max);
// Adding and subtracting 1.5 * 2^23 rounds a float of magnitude < 2^22 to an integer,
// to nearest even (the FPU's default mode), without SSE4.1's roundps.
constexpr float kRoundMagic = 12582912.0f;
// Values per block of the snorm16 loops: 4 vertices, so that the per-axis constants repeat
// with the block and the inner loop is three full SSE vectors.
constexpr std::size_t kBlock = 12;

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
  const uint32_t half = magnitude < (113u << 23) ? subnormal : normal;
  return static_cast<uint16_t>(half | sign);
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
  const uint32_t magnitude =
      exponent == kExponentMask ? special : (exponent == 0 ? tiny : rebiased);
  return std::bit_cast<float>(magnitude | (static_cast<uint32_t>(half) & 0x8000u) << 16);
}

inline uint16_t LoadU16(const std::byte* p) {
  uint16_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void StoreU16(std::byte* p, uint16_t v) { std::memcpy(p, &v, sizeof v); }

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

inline int16_t RoundToSnorm16(float t) {
  const float rounded = (t + kRoundMagic) - kRoundMagic;
  const float clamped = std::min(std::max(rounded, -32767.0f), 32767.0f);
  return static_cast<int16_t>(static_cast<int32_t>(clamped));
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
    StoreU16(o + 2 * i, HalfBitsOfFinite(v));
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
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const int a = static_cast<int>(i % 3);
    const double h = axes.half_extent[a];
    const double t =
        h > 0 ? (positions[i] - static_cast<double>(axes.centre[a])) / h * kSnorm16Max : 0.0;
    const double q = std::clamp(std::nearbyint(t), -32767.0, 32767.0);
    StoreU16(out.data() + 2 * i, static_cast<uint16_t>(static_cast<int16_t>(q)));
  }
}

Status EncodeSnorm16Positions(std::span<const float> positions, const Bounds& bounds,
                              std::span<std::byte> out, std::size_t first_vertex) {
  const std::size_t n = positions.size();
  const float* in = positions.data();
  std::byte* o = out.data();
  // The box check, in its own loop so both loops stay simple enough to vectorise.
  float lo[kBlock], hi[kBlock];
  for (std::size_t j = 0; j < kBlock; ++j) {
    lo[j] = bounds.min[j % 3];
    hi[j] = bounds.max[j % 3];
  }
  uint32_t bad = 0;
  std::size_t i = 0;
  for (; i + kBlock <= n; i += kBlock) {
    for (std::size_t j = 0; j < kBlock; ++j) bad |= !(in[i + j] >= lo[j] && in[i + j] <= hi[j]);
  }
  for (; i < n; ++i) bad |= !(in[i] >= lo[i % 3] && in[i] <= hi[i % 3]);
  if (bad != 0) {
    for (i = 0; i < n; ++i) {
      const int a = static_cast<int>(i % 3);
      if (in[i] >= bounds.min[a] && in[i] <= bounds.max[a]) continue;
      if (!std::isfinite(in[i]))
        return PositionError("is not finite", first_vertex + i / 3, a, in[i]);
      return PositionError(
          fmt::format("is outside the box [{}, {}]", bounds.min[a], bounds.max[a]).c_str(),
          first_vertex + i / 3, a, in[i]);
    }
  }

  const Snorm16Axes axes = AxesOf(bounds);
  if (!axes.finite_scale) {
    EncodeSnorm16PositionsInDouble(positions, axes, out);
    return Status::Ok();
  }
  float centre[kBlock], scale[kBlock];
  for (std::size_t j = 0; j < kBlock; ++j) {
    centre[j] = axes.centre[j % 3];
    scale[j] = axes.scale[j % 3];
  }
  for (i = 0; i + kBlock <= n; i += kBlock) {
    int16_t q[kBlock];
    for (std::size_t j = 0; j < kBlock; ++j)
      q[j] = RoundToSnorm16((in[i + j] - centre[j]) * scale[j]);
    std::memcpy(o + 2 * i, q, sizeof q);
  }
  for (; i < n; ++i) {
    const int16_t q = RoundToSnorm16((in[i] - centre[i % 3]) * scale[i % 3]);
    StoreU16(o + 2 * i, static_cast<uint16_t>(q));
  }
  return Status::Ok();
}

Status EncodeSnorm16Normals(std::span<const float> normals, std::span<std::byte> out,
                            std::size_t first_vertex) {
  const std::size_t n = normals.size();
  const float* in = normals.data();
  std::byte* o = out.data();
  constexpr float kLimit = 32767.5f;  // |n * 32767| below this rounds into [-32767, 32767]
  uint32_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float t = in[i] * static_cast<float>(kSnorm16Max);
    bad |= !(std::fabs(t) < kLimit);
    StoreU16(o + 2 * i, static_cast<uint16_t>(RoundToSnorm16(t)));
  }
  if (bad == 0) return Status::Ok();
  for (std::size_t i = 0; i < n; ++i) {
    if (std::fabs(in[i] * static_cast<float>(kSnorm16Max)) < kLimit) continue;
    return InvalidArgument(fmt::format("normals[vertex {}][{}] = {} is {}", first_vertex + i / 3,
                                       kAxisNames[i % 3], in[i],
                                       std::isfinite(in[i]) ? "outside [-1, 1]" : "not finite"));
  }
  return Status::Ok();
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
  for (std::size_t i = 0; i < out.size(); ++i) o[i] = FloatOfHalfBits(LoadU16(in + 2 * i));
}

Status DecodeValues(const char* field, VertexEncoding encoding, std::span<const std::byte> bytes,
                    std::span<float> out) {
  if (Status s = CheckDecodeLength(field, encoding, bytes, out.size()); !s.ok()) return s;
  switch (encoding) {
    case VertexEncoding::kFloat32:
      if (!bytes.empty()) std::memcpy(out.data(), bytes.data(), bytes.size());
      return Status::Ok();
    case VertexEncoding::kFloat16:
      DecodeFloat16(bytes, out);
      return Status::Ok();
    case VertexEncoding::kSnorm16:
      break;
  }
  return Internal("DecodeValues: snorm16 is decoded by its caller");
}

}  // namespace

const char* VertexEncodingName(VertexEncoding encoding) {
  switch (encoding) {
    case VertexEncoding::kFloat32:
      return "float32";
    case VertexEncoding::kFloat16:
      return "float16";
    case VertexEncoding::kSnorm16:
      return "snorm16";
  }
  return "unknown";
}

std::optional<VertexEncoding> ParseVertexEncoding(std::string_view name) {
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    if (name == VertexEncodingName(e)) return e;
  }
  return std::nullopt;
}

std::size_t EncodedBytesPerValue(VertexEncoding encoding) {
  return encoding == VertexEncoding::kFloat32 ? 4 : 2;
}

std::size_t EncodedBytes(VertexEncoding encoding, std::size_t vertex_count) {
  return vertex_count * kValuesPerVertex * EncodedBytesPerValue(encoding);
}

Result<Bounds> ComputeBounds(std::span<const float> positions, std::size_t first_vertex) {
  const std::size_t n = positions.size();
  if (n % 3 != 0) return NotATriple("positions", n);
  Bounds bounds;
  if (n == 0) return bounds;
  const float* in = positions.data();
  float lo[kBlock], hi[kBlock];
  for (std::size_t j = 0; j < kBlock; ++j) lo[j] = hi[j] = in[j % 3];
  // x - x is 0 for every finite x and NaN otherwise: one sum finds any non-finite value.
  float poison[kBlock] = {};
  std::size_t i = 0;
  for (; i + kBlock <= n; i += kBlock) {
    for (std::size_t j = 0; j < kBlock; ++j) {
      const float v = in[i + j];
      lo[j] = std::min(lo[j], v);
      hi[j] = std::max(hi[j], v);
      poison[j] += v - v;
    }
  }
  for (; i < n; ++i) {
    const std::size_t j = i % 3;
    lo[j] = std::min(lo[j], in[i]);
    hi[j] = std::max(hi[j], in[i]);
    poison[j] += in[i] - in[i];
  }
  bool finite = true;
  for (std::size_t j = 0; j < kBlock; ++j) finite = finite && poison[j] == 0.0f;
  if (!finite) {
    for (i = 0; i < n; ++i) {
      if (!std::isfinite(in[i])) {
        return PositionError("is not finite", first_vertex + i / 3, static_cast<int>(i % 3), in[i]);
      }
    }
  }
  for (int a = 0; a < 3; ++a) {
    bounds.min[a] = lo[a];
    bounds.max[a] = hi[a];
    for (std::size_t j = static_cast<std::size_t>(a) + 3; j < kBlock; j += 3) {
      bounds.min[a] = std::min(bounds.min[a], lo[j]);
      bounds.max[a] = std::max(bounds.max[a], hi[j]);
    }
  }
  return bounds;
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
  if (positions.size() % 3 != 0) return NotATriple("positions", positions.size());
  if (out.size() != positions.size() * EncodedBytesPerValue(encoding)) {
    return WrongOutputSize("positions", encoding, positions.size(), out.size());
  }
  switch (encoding) {
    case VertexEncoding::kFloat32:
      if (!out.empty()) std::memcpy(out.data(), positions.data(), out.size());
      return Status::Ok();
    case VertexEncoding::kFloat16:
      return EncodeFloat16("positions", positions, out, first_vertex);
    case VertexEncoding::kSnorm16:
      if (Status s = ValidateBounds(bounds); !s.ok()) return s;
      return EncodeSnorm16Positions(positions, bounds, out, first_vertex);
  }
  return InvalidArgument(fmt::format("encoding {} is unknown", static_cast<int>(encoding)));
}

Status EncodeNormals(VertexEncoding encoding, std::span<const float> normals,
                     std::span<std::byte> out, std::size_t first_vertex) {
  if (normals.size() % 3 != 0) return NotATriple("normals", normals.size());
  if (out.size() != normals.size() * EncodedBytesPerValue(encoding)) {
    return WrongOutputSize("normals", encoding, normals.size(), out.size());
  }
  switch (encoding) {
    case VertexEncoding::kFloat32:
      if (!out.empty()) std::memcpy(out.data(), normals.data(), out.size());
      return Status::Ok();
    case VertexEncoding::kFloat16:
      return EncodeFloat16("normals", normals, out, first_vertex);
    case VertexEncoding::kSnorm16:
      return EncodeSnorm16Normals(normals, out, first_vertex);
  }
  return InvalidArgument(fmt::format("encoding {} is unknown", static_cast<int>(encoding)));
}

Status DecodePositions(VertexEncoding encoding, std::span<const std::byte> bytes,
                       const Bounds& bounds, std::span<float> out) {
  if (encoding != VertexEncoding::kSnorm16) return DecodeValues("positions", encoding, bytes, out);
  if (Status s = CheckDecodeLength("positions", encoding, bytes, out.size()); !s.ok()) return s;
  if (out.size() % 3 != 0) return NotATriple("positions", out.size());
  if (Status s = ValidateBounds(bounds); !s.ok()) return s;
  const Snorm16Axes axes = AxesOf(bounds);
  float centre[kBlock], step[kBlock];
  for (std::size_t j = 0; j < kBlock; ++j) {
    centre[j] = axes.centre[j % 3];
    step[j] = axes.half_extent[j % 3];
  }
  const std::size_t n = out.size();
  const std::byte* in = bytes.data();
  float* o = out.data();
  std::size_t i = 0;
  for (; i + kBlock <= n; i += kBlock) {
    int16_t q[kBlock];
    std::memcpy(q, in + 2 * i, sizeof q);
    for (std::size_t j = 0; j < kBlock; ++j) {
      o[i + j] = centre[j] + (static_cast<float>(q[j]) * kInvSnorm16Max) * step[j];
    }
  }
  for (; i < n; ++i) {
    const auto q = static_cast<int16_t>(LoadU16(in + 2 * i));
    o[i] = centre[i % 3] + (static_cast<float>(q) * kInvSnorm16Max) * step[i % 3];
  }
  return Status::Ok();
}

Status DecodeNormals(VertexEncoding encoding, std::span<const std::byte> bytes,
                     std::span<float> out) {
  if (encoding != VertexEncoding::kSnorm16) return DecodeValues("normals", encoding, bytes, out);
  if (Status s = CheckDecodeLength("normals", encoding, bytes, out.size()); !s.ok()) return s;
  const std::byte* in = bytes.data();
  float* o = out.data();
  for (std::size_t i = 0; i < out.size(); ++i) {
    o[i] = static_cast<float>(static_cast<int16_t>(LoadU16(in + 2 * i))) * kInvSnorm16Max;
  }
  return Status::Ok();
}

double PositionEncodingError(VertexEncoding encoding, const Bounds& bounds, int axis, double x) {
  switch (encoding) {
    case VertexEncoding::kFloat32:
      return 0.0;
    case VertexEncoding::kFloat16:
      return std::max(std::fabs(x) * 0x1p-11, 0x1p-25);
    case VertexEncoding::kSnorm16: {
      const double lo = bounds.min[axis];
      const double hi = bounds.max[axis];
      const double magnitude = std::max({std::fabs(lo), std::fabs(hi), 0x1p-126});
      return (hi - lo) / 131068.0 + 0x1p-20 * magnitude;
    }
  }
  return 0.0;
}

double NormalEncodingError(VertexEncoding encoding, double n) {
  switch (encoding) {
    case VertexEncoding::kFloat32:
      return 0.0;
    case VertexEncoding::kFloat16:
      return std::max(std::fabs(n) * 0x1p-11, 0x1p-25);
    case VertexEncoding::kSnorm16:
      return 1.0 / 65534.0 + 0x1p-24;
  }
  return 0.0;
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
