// The vertex encodings against independent float64 computations: binary16 rounding from a
// table of every half value built from the IEEE formula, each stated error bound computed
// here in double from its formula, boxes from a plain min/max in double.
#include "skinserve/encoding/vertex_encoding.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "skinserve/engine/simd_targets.h"

namespace skinserve {
namespace {

constexpr float kFloatMax = std::numeric_limits<float>::max();

// The value of binary16 bits, from the IEEE 754 formula, in double (inf/NaN included).
double HalfValue(uint16_t bits) {
  const int sign = (bits & 0x8000) ? -1 : 1;
  const int exponent = (bits >> 10) & 0x1f;
  const int mantissa = bits & 0x3ff;
  if (exponent == 31) {
    return mantissa == 0 ? sign * std::numeric_limits<double>::infinity()
                         : std::numeric_limits<double>::quiet_NaN();
  }
  if (exponent == 0) return sign * std::ldexp(mantissa, -24);
  return sign * std::ldexp(1.0 + mantissa / 1024.0, exponent - 15);
}

// Nearest half to x (finite, |x| < 65520), ties to the even bit pattern, by searching
// the table of every non-negative finite half (their bit patterns are in value order).
uint16_t ReferenceHalf(double x) {
  static const std::vector<double> table = [] {
    std::vector<double> t;
    for (uint32_t bits = 0; bits <= 0x7bff; ++bits)
      t.push_back(HalfValue(static_cast<uint16_t>(bits)));
    return t;
  }();
  const double magnitude = std::fabs(x);
  const auto upper = std::lower_bound(table.begin(), table.end(), magnitude);
  uint16_t bits;
  if (upper == table.end()) {
    bits = magnitude - table.back() < std::ldexp(1.0, 4) ? 0x7bff : 0x7c00;  // 65504 or inf
  } else if (*upper == magnitude || upper == table.begin()) {
    bits = static_cast<uint16_t>(upper - table.begin());
  } else {
    const auto hi = static_cast<uint16_t>(upper - table.begin());
    const auto lo = static_cast<uint16_t>(hi - 1);
    const double below = magnitude - table[lo];
    const double above = table[hi] - magnitude;
    bits = below < above ? lo : above < below ? hi : ((lo & 1) == 0 ? lo : hi);
  }
  return static_cast<uint16_t>(bits | (std::signbit(x) ? 0x8000 : 0));
}

std::vector<std::byte> Encoded(VertexEncoding e, std::span<const float> values, const Bounds& b,
                               bool normals = false) {
  std::vector<std::byte> out(values.size() * EncodedBytesPerValue(e));
  const Status s = normals ? EncodeNormals(e, values, out) : EncodePositions(e, values, b, out);
  EXPECT_TRUE(s.ok()) << s.ToString();
  return out;
}

uint16_t U16At(const std::vector<std::byte>& bytes, std::size_t i) {
  uint16_t v;
  std::memcpy(&v, bytes.data() + 2 * i, 2);
  return v;
}

// A float of random sign and magnitude spread over [2^lo, 2^hi) log-uniformly.
float LogUniform(std::mt19937& rng, int lo, int hi) {
  std::uniform_real_distribution<double> e(lo, hi);
  const double m = std::exp2(e(rng));
  return static_cast<float>(rng() & 1 ? m : -m);
}

// Every test runs at each SIMD target this machine runs (the snorm16 loops are dispatched
// at run time to the best one: AVX-512, AVX2, SSE4, the scalar fallback...).
class VertexEncodingTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    const Status s = CapSimdDispatch(GetParam());
    ASSERT_TRUE(s.ok()) << s.ToString();
  }
  void TearDown() override { EXPECT_TRUE(CapSimdDispatch("").ok()); }
};

INSTANTIATE_TEST_SUITE_P(EachSimdTarget, VertexEncodingTest,
                         ::testing::ValuesIn(RunnableSimdTargets()),
                         [](const ::testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param;
                         });

TEST_P(VertexEncodingTest, NamesSizesAndParsing) {
  EXPECT_STREQ(VertexEncodingName(VertexEncoding::kSnorm16), "snorm16");
  EXPECT_EQ(ParseVertexEncoding("float16"), VertexEncoding::kFloat16);
  EXPECT_EQ(ParseVertexEncoding("float32"), VertexEncoding::kFloat32);
  EXPECT_FALSE(ParseVertexEncoding("half").has_value());
  EXPECT_EQ(EncodedBytes(VertexEncoding::kFloat32, 10), 120u);
  EXPECT_EQ(EncodedBytes(VertexEncoding::kFloat16, 10), 60u);
  EXPECT_EQ(EncodedBytes(VertexEncoding::kSnorm16, 10), 60u);
}

// The table every encoding is described in: its rows in the order of their values (the
// wire's numbers), each name parsed back to it, and each row's kernels keeping its own
// stated bound on random values in and beyond [-1, 1].
TEST_P(VertexEncodingTest, TheTableDescribesEveryEncodingOnce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(-1, 1), wide(-300, 300);
  int index = 0;
  for (const EncodingDescription& e : Encodings()) {
    EXPECT_EQ(static_cast<int>(e.id), index++) << e.name;
    EXPECT_EQ(DescribeEncoding(e.id), &e);
    EXPECT_EQ(ParseVertexEncoding(e.name), e.id);
    EXPECT_EQ(EncodedBytesPerValue(e.id), e.bytes_per_value);
    for (bool normals : {false, true}) {
      std::vector<float> values(3 * 1001);
      for (float& v : values) v = normals ? unit(rng) : wide(rng);
      Bounds box;
      if (e.quantized_to_box && !normals) box = ComputeBounds(values).value();
      std::vector<std::byte> bytes(values.size() * e.bytes_per_value);
      ASSERT_TRUE(e.encode(values, normals, box, bytes, 0).ok()) << e.name;
      std::vector<float> decoded(values.size());
      ASSERT_TRUE(e.decode(bytes, normals, box, decoded).ok()) << e.name;
      for (std::size_t i = 0; i < values.size(); ++i) {
        const double bound = e.error(normals, box, static_cast<int>(i % 3), values[i]);
        ASSERT_LE(std::fabs(double{decoded[i]} - values[i]), bound + 1e-12)
            << e.name << (normals ? " normals" : " positions") << " value " << i;
      }
    }
  }
  EXPECT_EQ(index, 3);
  EXPECT_EQ(DescribeEncoding(static_cast<VertexEncoding>(3)), nullptr);
  EXPECT_FALSE(QuantizedToBox(static_cast<VertexEncoding>(7)));
}

TEST_P(VertexEncodingTest, HalfToFloatIsExactForEveryHalf) {
  for (uint32_t bits = 0; bits <= 0xffff; ++bits) {
    const double expected = HalfValue(static_cast<uint16_t>(bits));
    const float got = HalfToFloat(static_cast<uint16_t>(bits));
    if (std::isnan(expected)) {
      EXPECT_TRUE(std::isnan(got)) << bits;
    } else {
      ASSERT_EQ(static_cast<double>(got), expected) << "bits " << bits;
      ASSERT_EQ(std::signbit(got), (bits & 0x8000) != 0) << "bits " << bits;
    }
  }
}

TEST_P(VertexEncodingTest, FloatToHalfRoundsToNearestEvenLikeTheReference) {
  std::vector<float> values = {
      0.0f,           -0.0f,          65504.0f,       -65504.0f, 65519.99f, 6.1035156e-05f,
      5.9604645e-08f, 2.9802322e-08f, 2.9802326e-08f, 1e-30f,    1.0f};
  // Every midpoint between neighbouring halves (the ties) and the floats either side.
  for (uint32_t bits = 0; bits < 0x7bff; ++bits) {
    const double mid =
        (HalfValue(static_cast<uint16_t>(bits)) + HalfValue(static_cast<uint16_t>(bits + 1))) / 2;
    const auto f = static_cast<float>(mid);
    ASSERT_EQ(static_cast<double>(f), mid);  // a float holds every midpoint exactly
    for (float v : {f, std::nextafter(f, 0.0f), std::nextafter(f, kFloatMax)}) {
      values.push_back(v);
      values.push_back(-v);
    }
  }
  std::mt19937 rng(11);
  for (int i = 0; i < 200000; ++i) values.push_back(LogUniform(rng, -30, 16));
  for (float v : values) {
    ASSERT_EQ(FloatToHalf(v), ReferenceHalf(v)) << v;
  }
  // The loop encoder agrees with the scalar one wherever it accepts the value.
  std::vector<float> in_range;
  for (float v : values) {
    if (std::fabs(v) <= kFloat16Max) in_range.push_back(v);
  }
  in_range.resize(in_range.size() + 2 - (in_range.size() + 2) % 3, 1.0f);  // x y z triples
  const std::vector<std::byte> bytes = Encoded(VertexEncoding::kFloat16, in_range, {});
  for (std::size_t i = 0; i < in_range.size(); ++i) {
    ASSERT_EQ(U16At(bytes, i), ReferenceHalf(in_range[i])) << in_range[i];
  }
}

TEST_P(VertexEncodingTest, FloatToHalfKeepsInfinityAndNan) {
  EXPECT_EQ(FloatToHalf(std::numeric_limits<float>::infinity()), 0x7c00);
  EXPECT_EQ(FloatToHalf(-std::numeric_limits<float>::infinity()), 0xfc00);
  EXPECT_EQ(FloatToHalf(65520.0f), 0x7c00);  // the tie above 65504 rounds to even: infinity
  EXPECT_EQ(FloatToHalf(1e30f), 0x7c00);
  EXPECT_TRUE(std::isnan(HalfToFloat(FloatToHalf(std::numeric_limits<float>::quiet_NaN()))));
}

TEST_P(VertexEncodingTest, Float16WithinItsStatedBound) {
  std::mt19937 rng(7);
  std::vector<float> values;
  for (int i = 0; i < 60000; ++i) values.push_back(LogUniform(rng, -28, 16));
  for (float v : {65504.0f, -65504.0f, 0.0f, -0.0f, 1e-8f, -3e-6f}) values.push_back(v);
  const std::vector<std::byte> bytes = Encoded(VertexEncoding::kFloat16, values, {});
  std::vector<float> decoded(values.size());
  ASSERT_TRUE(DecodePositions(VertexEncoding::kFloat16, bytes, {}, decoded).ok());
  double worst_ratio = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double x = values[i];
    const double bound = std::max(std::fabs(x) * std::ldexp(1.0, -11), std::ldexp(1.0, -25));
    const double error = std::fabs(decoded[i] - x);
    ASSERT_LE(error, bound) << x;
    worst_ratio = std::max(worst_ratio, error / bound);
    ASSERT_EQ(PositionEncodingError(VertexEncoding::kFloat16, {}, 0, x), bound);
  }
  EXPECT_GT(worst_ratio, 0.9);  // the bound is tight: random values come close to it
}

TEST_P(VertexEncodingTest, Float16RefusesOverflowAndNanNamingTheVertex) {
  std::vector<float> values(12, 1.0f);
  std::vector<std::byte> out(values.size() * 2);
  values[7] = std::nextafter(65504.0f, kFloatMax);  // vertex 2, y
  Status s = EncodePositions(VertexEncoding::kFloat16, values, {}, out);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("positions[vertex 2][y]"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("65504"), std::string::npos) << s.message();
  // Numbered from the part's first vertex.
  s = EncodePositions(VertexEncoding::kFloat16, values, {}, out, 100);
  EXPECT_NE(s.message().find("positions[vertex 102][y]"), std::string::npos) << s.message();
  values[7] = -65504.0f;
  EXPECT_TRUE(EncodePositions(VertexEncoding::kFloat16, values, {}, out).ok());
  values[9] = std::numeric_limits<float>::quiet_NaN();
  s = EncodeNormals(VertexEncoding::kFloat16, values, out);
  EXPECT_NE(s.message().find("normals[vertex 3][x]"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("not finite"), std::string::npos) << s.message();
}

TEST_P(VertexEncodingTest, Float32IsTheBytesAsTheyAre) {
  const std::vector<float> values = {1.5f, -0.0f, 3e38f, 1e-45f, -7.25f, 2.0f};
  const std::vector<std::byte> bytes = Encoded(VertexEncoding::kFloat32, values, {});
  EXPECT_EQ(std::memcmp(bytes.data(), values.data(), bytes.size()), 0);
  std::vector<float> decoded(values.size());
  ASSERT_TRUE(DecodeNormals(VertexEncoding::kFloat32, bytes, decoded).ok());
  EXPECT_EQ(std::memcmp(decoded.data(), values.data(), bytes.size()), 0);
}

// Encodes `positions` to snorm16 in the box ComputeBounds finds, decodes, and checks the
// box against a double min/max, each q against the contract's formula in double, and each
// value against the stated bound computed here. Returns the worst error / half a step.
double CheckSnorm16(const std::vector<float>& positions) {
  Result<Bounds> bounds = ComputeBounds(positions);
  EXPECT_TRUE(bounds.ok()) << bounds.status().ToString();
  if (!bounds.ok()) return 0;
  const Bounds& b = *bounds;
  for (int a = 0; a < 3; ++a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = a; i < positions.size(); i += 3) {
      lo = std::min(lo, static_cast<double>(positions[i]));
      hi = std::max(hi, static_cast<double>(positions[i]));
    }
    EXPECT_EQ(b.min[a], lo);
    EXPECT_EQ(b.max[a], hi);
  }
  const std::vector<std::byte> bytes = Encoded(VertexEncoding::kSnorm16, positions, b);
  std::vector<float> decoded(positions.size());
  const Status s = DecodePositions(VertexEncoding::kSnorm16, bytes, b, decoded);
  EXPECT_TRUE(s.ok()) << s.ToString();
  double worst = 0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const int a = static_cast<int>(i % 3);
    const double lo = b.min[a], hi = b.max[a], x = positions[i];
    const double c = (lo + hi) / 2, h = (hi - lo) / 2;
    const double half_step = (hi - lo) / 131068;
    const double magnitude = std::max({std::fabs(lo), std::fabs(hi), 0x1p-126});
    const double bound = half_step + std::ldexp(1.0, -20) * magnitude;
    // q is the contract's rounding of t, give or take the encoder's float32 rounding
    // (half the rounding term of the bound, in steps).
    const auto q = static_cast<int16_t>(U16At(bytes, i));
    const double t = h > 0 ? (x - c) / h * 32767 : 0.0;
    const double slack = h > 0 ? std::ldexp(1.0, -21) * magnitude / (2 * half_step) : 0.0;
    EXPECT_LE(std::fabs(q - t), 0.5 + slack) << "value " << i << " x " << x;
    const double error = std::fabs(decoded[i] - x);
    EXPECT_LE(error, bound) << "value " << i << " x " << x << " box [" << lo << ", " << hi << "]";
    EXPECT_EQ(PositionEncodingError(VertexEncoding::kSnorm16, b, a, x), bound);
    if (half_step > 0) worst = std::max(worst, error / half_step);
  }
  return worst;
}

TEST_P(VertexEncodingTest, Snorm16PositionsWithinHalfAStepInRandomBoxes) {
  std::mt19937 rng(3);
  for (int box = 0; box < 40; ++box) {
    std::uniform_real_distribution<float> centre(-1000.0f, 1000.0f);
    const float cx = centre(rng), cy = centre(rng), cz = centre(rng);
    const float extent = std::exp2(std::uniform_real_distribution<float>(-8.0f, 10.0f)(rng));
    std::uniform_real_distribution<float> offset(-extent, extent);
    std::vector<float> positions;
    for (int v = 0; v < 2001; ++v) {  // not a multiple of the 4-vertex block: the tail runs
      positions.push_back(cx + offset(rng));
      positions.push_back(cy + offset(rng) * 0.5f);
      positions.push_back(cz + offset(rng) * 0.01f);
    }
    const double worst = CheckSnorm16(positions);
    if (extent > 64.0f) {  // steps far above float32's spacing: the half step is reached
      EXPECT_GT(worst, 0.9) << "box " << box;
    }
  }
}

TEST_P(VertexEncodingTest, Snorm16EdgeBoxes) {
  // Zero extent on every axis: q = 0 and x' = c exactly.
  std::vector<float> flat = {1.5f, -2.0f, 3.0f, 1.5f, -2.0f, 3.0f};
  CheckSnorm16(flat);
  std::vector<std::byte> bytes(flat.size() * 2);
  ASSERT_TRUE(EncodePositions(VertexEncoding::kSnorm16, flat, *ComputeBounds(flat), bytes).ok());
  for (std::size_t i = 0; i < flat.size(); ++i) EXPECT_EQ(U16At(bytes, i), 0);
  // One axis flat, the others not; the float16 range's ends; a box near +-FLT_MAX;
  // subnormal boxes; a box too thin for a float scale.
  CheckSnorm16({0, 5, 1, 10, 5, -1, 3, 5, 0.25f});
  CheckSnorm16({-65504, 65504, 1, 65504, -65504, 2});
  CheckSnorm16({-kFloatMax, kFloatMax, 0, kFloatMax, -kFloatMax, 1e30f, 0, 1, -1e30f});
  CheckSnorm16({0, -1e-40f, 1e-42f, 1e-40f, 1e-40f, 2e-42f, 5e-41f, 0, 0});
  CheckSnorm16({0, 1, 2, 1e-35f, 1, 2, 3e-36f, 1, 2});
  CheckSnorm16({1000, 1000, 1000, std::nextafter(1000.0f, 2000.0f), 1000, 1000});
  // A single vertex, an empty frame.
  CheckSnorm16({1, 2, 3});
  Result<Bounds> empty = ComputeBounds({});
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(*empty, Bounds{});
}

TEST_P(VertexEncodingTest, BoundsRefuseNonFiniteNamingTheVertex) {
  // 101 vertices: whole vector blocks at every target (16 vertices at AVX-512), then a tail.
  std::vector<float> positions(303, 1.0f);
  positions[25] = std::numeric_limits<float>::quiet_NaN();  // vertex 8, y
  Result<Bounds> b = ComputeBounds(positions);
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("positions[vertex 8][y]"), std::string::npos)
      << b.status().message();
  positions[25] = -std::numeric_limits<float>::infinity();
  b = ComputeBounds(positions, 40);
  EXPECT_NE(b.status().message().find("positions[vertex 48][y]"), std::string::npos)
      << b.status().message();
  positions[25] = 1.0f;
  positions[4] = std::numeric_limits<float>::infinity();  // vertex 1, y
  b = ComputeBounds(positions);
  EXPECT_NE(b.status().message().find("positions[vertex 1][y]"), std::string::npos)
      << b.status().message();
  positions[4] = 1.0f;
  positions[302] = std::numeric_limits<float>::quiet_NaN();  // vertex 100, z: the tail
  b = ComputeBounds(positions);
  EXPECT_NE(b.status().message().find("positions[vertex 100][z]"), std::string::npos)
      << b.status().message();
  positions.assign(3, 1.0f);
  positions[0] = std::numeric_limits<float>::infinity();  // the first vertex seeds the box
  EXPECT_FALSE(ComputeBounds(positions).ok());
  EXPECT_FALSE(ComputeBounds(std::vector<float>(4, 0.0f)).ok());  // not x y z triples
}

TEST_P(VertexEncodingTest, Snorm16RefusesValuesOutsideTheBox) {
  std::vector<float> positions = {0, 0, 0, 1, 1, 1, 0.5f, 0.5f, 0.5f};
  positions.resize(303, 0.25f);  // 101 vertices: the vector blocks and the tail
  Bounds box = *ComputeBounds(positions);
  std::vector<std::byte> out(positions.size() * 2);
  positions[5] = 1.01f;  // vertex 1, z
  Status s = EncodePositions(VertexEncoding::kSnorm16, positions, box, out);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("positions[vertex 1][z]"), std::string::npos) << s.message();
  positions[5] = std::numeric_limits<float>::quiet_NaN();
  s = EncodePositions(VertexEncoding::kSnorm16, positions, box, out);
  EXPECT_NE(s.message().find("not finite"), std::string::npos) << s.message();
  positions[5] = 0.5f;
  positions[301] = -0.01f;  // vertex 100, y: in the tail
  s = EncodePositions(VertexEncoding::kSnorm16, positions, box, out);
  EXPECT_NE(s.message().find("positions[vertex 100][y]"), std::string::npos) << s.message();
  positions[301] = 0.5f;
  EXPECT_TRUE(EncodePositions(VertexEncoding::kSnorm16, positions, box, out).ok());
  box.max[1] = std::numeric_limits<float>::infinity();
  s = EncodePositions(VertexEncoding::kSnorm16, positions, box, out);
  EXPECT_NE(s.message().find("bounds.max_y"), std::string::npos) << s.message();
}

// The wire's bytes may start anywhere: decoding from an odd address gives the same floats.
TEST_P(VertexEncodingTest, DecodesFromBytesAtAnyAlignment) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  std::vector<float> positions(3 * 77), normals(3 * 77);
  for (float& v : positions) v = u(rng);
  for (float& v : normals) v = u(rng) / 3.0f;
  const Bounds box = *ComputeBounds(positions);
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    SCOPED_TRACE(VertexEncodingName(e));
    const std::vector<std::byte> p = Encoded(e, positions, box);
    const std::vector<std::byte> n = Encoded(e, normals, {}, true);
    for (std::size_t offset : {1, 3}) {
      std::vector<std::byte> shifted(offset + p.size());
      std::copy(p.begin(), p.end(), shifted.begin() + offset);
      std::vector<float> aligned(positions.size()), odd(positions.size());
      ASSERT_TRUE(DecodePositions(e, p, box, aligned).ok());
      ASSERT_TRUE(DecodePositions(e, std::span(shifted).subspan(offset), box, odd).ok());
      EXPECT_EQ(aligned, odd) << "offset " << offset;
      std::copy(n.begin(), n.end(), shifted.begin() + offset);
      ASSERT_TRUE(DecodeNormals(e, n, aligned).ok());
      ASSERT_TRUE(DecodeNormals(e, std::span(shifted).subspan(offset), odd).ok());
      EXPECT_EQ(aligned, odd) << "offset " << offset;
      // And encoding into an odd address writes the same bytes.
      std::vector<std::byte> out(offset + p.size());
      ASSERT_TRUE(
          EncodePositions(e, positions, box, std::span(out).subspan(offset, p.size())).ok());
      EXPECT_TRUE(std::equal(p.begin(), p.end(), out.begin() + offset)) << "offset " << offset;
    }
  }
}

TEST_P(VertexEncodingTest, Snorm16NormalsWithinTheirBound) {
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  std::vector<float> normals;
  for (int v = 0; v < 20000; ++v) {
    float n[3] = {g(rng), g(rng), g(rng)};
    const float length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (float c : n) normals.push_back(c / length);
  }
  for (float c : {1.0f, -1.0f, 0.0f, std::nextafter(1.0f, 2.0f), -std::nextafter(1.0f, 2.0f)}) {
    normals.push_back(c);
  }
  normals.push_back(0);
  const std::vector<std::byte> bytes = Encoded(VertexEncoding::kSnorm16, normals, {}, true);
  std::vector<float> decoded(normals.size());
  ASSERT_TRUE(DecodeNormals(VertexEncoding::kSnorm16, bytes, decoded).ok());
  double worst = 0;
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const double n = normals[i];
    const double bound = 1.0 / 65534 + std::ldexp(1.0, -24);
    const double error = std::fabs(decoded[i] - n);
    ASSERT_LE(error, bound) << n;
    ASSERT_LE(std::fabs(static_cast<int16_t>(U16At(bytes, i)) - n * 32767), 0.5 + 1e-3) << n;
    worst = std::max(worst, error * 65534);
  }
  EXPECT_GT(worst, 0.9);
  EXPECT_EQ(static_cast<int16_t>(U16At(bytes, normals.size() - 6)), 32767);   // 1
  EXPECT_EQ(static_cast<int16_t>(U16At(bytes, normals.size() - 5)), -32767);  // -1
}

TEST_P(VertexEncodingTest, Snorm16NormalsRefuseOutOfRangeNamingTheVertex) {
  std::vector<float> normals = {0, 0, 1, 0, 1, 0, 1.001f, 0, 0};
  std::vector<std::byte> out(normals.size() * 2);
  Status s = EncodeNormals(VertexEncoding::kSnorm16, normals, out);
  EXPECT_NE(s.message().find("normals[vertex 2][x]"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("outside [-1, 1]"), std::string::npos) << s.message();
  normals[6] = std::numeric_limits<float>::quiet_NaN();
  s = EncodeNormals(VertexEncoding::kSnorm16, normals, out);
  EXPECT_NE(s.message().find("not finite"), std::string::npos) << s.message();
  // In the vector loop at every target: 101 vertices, vertex 70's y out of range.
  normals.assign(303, 0.5f);
  normals[211] = -1.01f;
  out.resize(normals.size() * 2);
  s = EncodeNormals(VertexEncoding::kSnorm16, normals, out);
  EXPECT_NE(s.message().find("normals[vertex 70][y]"), std::string::npos) << s.message();
  normals[211] = std::numeric_limits<float>::infinity();
  s = EncodeNormals(VertexEncoding::kSnorm16, normals, out);
  EXPECT_NE(s.message().find("not finite"), std::string::npos) << s.message();
}

TEST_P(VertexEncodingTest, BadLengthsAreErrorsNamingTheField) {
  std::vector<float> out(6);
  std::vector<std::byte> bytes(11);
  Status s = DecodePositions(VertexEncoding::kFloat16, bytes, {}, out);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("positions: 11 bytes, expected 12"), std::string::npos) << s.message();
  s = DecodeNormals(VertexEncoding::kFloat32, bytes, out);
  EXPECT_NE(s.message().find("normals: 11 bytes, expected 24"), std::string::npos) << s.message();
  s = DecodeNormals(VertexEncoding::kSnorm16, bytes, out);
  EXPECT_NE(s.message().find("normals"), std::string::npos) << s.message();
  bytes.resize(12);
  Bounds inverted;
  inverted.min = {0, 2, 0};
  inverted.max = {1, 1, 1};
  s = DecodePositions(VertexEncoding::kSnorm16, bytes, inverted, out);
  EXPECT_NE(s.message().find("bounds.max_y"), std::string::npos) << s.message();
  const std::vector<float> values(6, 1.0f);
  s = EncodePositions(VertexEncoding::kSnorm16, values, *ComputeBounds(values), bytes);
  EXPECT_TRUE(s.ok()) << s.ToString();
  s = EncodePositions(VertexEncoding::kFloat32, values, {}, bytes);
  EXPECT_NE(s.message().find("positions: 6 values of float32 need 24 bytes"), std::string::npos)
      << s.message();
}

}  // namespace
}  // namespace skinserve
