// The quantized rest stream (quantized_rest.h) on `simd` and `simd-openmp` at every SIMD
// target this binary and CPU run, against two float64 references written here:
//  1. on the DEQUANTIZED input (offset + scale * q in float64, q / steps weights, the last
//     1 - their sum, snorm16 normals): the kernel's own float32 rounding only, the
//     tolerance of CompareWithReference (1e-5 * (1 + S), normals 1e-5);
//  2. on the ORIGINAL float input: the stated bound, per output coordinate r
//       sum_k |M[r][k]| * scale_k / 2                         (positions, half a step)
//     + sum_{i < B-1} (1 / steps) * |((M_i - M_last) p)[r]|    (weights, < 1 step each)
//     + the float32 tolerance above,
//     with M the matrix blended with the decoded weights; and, over the frame, the worst
//     error relative to the mesh's extent against the rigid-palette figure the docs state.
// Random valid meshes: every influence count, 8- and 16-bit joints, with and without
// normals, both weight widths, meshes moved off the origin, tails around the chunks. Also:
// the other backends skin the decoded floats; dual quaternions and morph targets are
// refused with their reason; ids and byte sizes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "backend_fixture.h"
#include "reference_cases.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

struct Case {
  uint32_t vertices;
  uint32_t influences;
  uint32_t joints;
  bool normals;
  RestEncoding encoding;
};

// A synthetic mesh moved off the origin by a seed-dependent amount, so the box's offset
// matters.
MeshArrays RandomMesh(const Case& c, uint64_t seed) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = c.vertices,
                                         .influences = c.influences,
                                         .joint_count = c.joints,
                                         .normals = c.normals,
                                         .seed = seed});
  const float shift[3] = {static_cast<float>(seed % 7) * 3.5f - 10.0f, 4.0f,
                          -static_cast<float>(seed % 5)};
  for (std::size_t i = 0; i < arrays.positions.size(); ++i) arrays.positions[i] += shift[i % 3];
  return arrays;
}

double Steps(RestEncoding e) {
  return e == RestEncoding::kQuantized8Weights ? kWeightSteps8 : kWeightSteps16;
}

// One vertex's input as float64.
struct Vertex {
  double p[3];
  double n[3];
  double w[kMaxInfluences];
};

Vertex Decoded(const QuantizedRest& q, uint32_t b, std::size_t v) {
  Vertex x{};
  for (int a = 0; a < 3; ++a) {
    x.p[a] = double{q.offset[a]} + double{q.scale[a]} * q.positions[3 * v + a];
    if (!q.normals.empty()) x.n[a] = q.normals[3 * v + a] / 32767.0;
  }
  double sum = 0;
  for (uint32_t i = 0; i + 1 < b; ++i) {
    const double stored =
        q.weights8.empty() ? q.weights16[v * (b - 1) + i] : q.weights8[v * (b - 1) + i];
    x.w[i] = stored / Steps(q.encoding);
    sum += x.w[i];
  }
  x.w[b - 1] = 1.0 - sum;
  return x;
}

Vertex Original(const MeshArrays& a, std::size_t v) {
  Vertex x{};
  for (int k = 0; k < 3; ++k) {
    x.p[k] = a.positions[3 * v + k];
    if (!a.normals.empty()) x.n[k] = a.normals[3 * v + k];
  }
  // Mesh::Create renormalises weights to sum exactly 1: so does this reference.
  double sum = 0;
  for (uint32_t i = 0; i < a.influences; ++i) sum += a.weights[v * a.influences + i];
  for (uint32_t i = 0; i < a.influences; ++i) x.w[i] = a.weights[v * a.influences + i] / sum;
  return x;
}

// The blended matrix sum_i w_i M_i (equation 3), 3x4 row-major, in float64.
void Blend(std::span<const float> palette, const uint16_t* joints, const double* w, uint32_t b,
           double m[12]) {
  std::fill(m, m + 12, 0.0);
  for (uint32_t i = 0; i < b; ++i) {
    for (int e = 0; e < 12; ++e) m[e] += w[i] * palette[12 * joints[i] + e];
  }
}

// max |p| * max row sum of |M| + max |t| over the frame: the float32 term of the tolerance
// (as CompareWithReference).
double FloatTolerance(std::span<const float> palette, const MeshArrays& a) {
  double max_p = 0, max_row = 0, max_t = 0;
  for (float x : a.positions) max_p = std::max(max_p, std::fabs(double{x}));
  for (std::size_t j = 0; j < palette.size() / 12; ++j) {
    for (int r = 0; r < 3; ++r) {
      double row = 0;
      for (int c = 0; c < 3; ++c) row += std::fabs(palette[12 * j + 4 * r + c]);
      max_row = std::max(max_row, row);
      max_t = std::max(max_t, std::fabs(double{palette[12 * j + 4 * r + 3]}));
    }
  }
  return 1e-5 * (1 + max_p * max_row + max_t);
}

struct Errors {
  double dequantized_position = 0;  // against reference 1
  double dequantized_normal = 0;
  double over_bound = 0;  // against reference 2: the largest error / bound
  double relative_to_extent = 0;
};

Errors Check(const Mesh& mesh, const MeshArrays& original, std::span<const float> palette,
             std::span<const float> positions, std::span<const float> normals) {
  const QuantizedRest& q = *mesh.quantized_rest();
  const uint32_t b = mesh.influences();
  const double float_tolerance = FloatTolerance(palette, original);
  double extent = 0;
  for (int a = 0; a < 3; ++a) extent = std::max(extent, double{q.scale[a]} * kPositionSteps);
  Errors e;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const uint16_t* joints = original.joints.data() + v * b;
    const Vertex d = Decoded(q, b, v), o = Original(original, v);
    double m[12];
    Blend(palette, joints, d.w, b, m);
    for (int r = 0; r < 3; ++r) {
      const double* row = m + 4 * r;
      const double got = positions[3 * v + r];
      const double dequantized = row[0] * d.p[0] + row[1] * d.p[1] + row[2] * d.p[2] + row[3];
      e.dequantized_position = std::max(e.dequantized_position, std::fabs(got - dequantized));
      // Reference 2: the original input, and the bound.
      double mo[12];
      Blend(palette, joints, o.w, b, mo);
      const double* ro = mo + 4 * r;
      const double exact = ro[0] * o.p[0] + ro[1] * o.p[1] + ro[2] * o.p[2] + ro[3];
      double bound = float_tolerance;
      for (int k = 0; k < 3; ++k) bound += std::fabs(row[k]) * q.scale[k] / 2;
      const float* last = palette.data() + 12 * joints[b - 1];
      for (uint32_t i = 0; i + 1 < b; ++i) {
        const float* mi = palette.data() + 12 * joints[i];
        double diff = mi[4 * r + 3] - last[4 * r + 3];
        for (int k = 0; k < 3; ++k) diff += (mi[4 * r + k] - last[4 * r + k]) * o.p[k];
        bound += std::fabs(diff) / Steps(q.encoding);
      }
      const double error = std::fabs(got - exact);
      e.over_bound = std::max(e.over_bound, std::isnan(got) ? 1e30 : error / bound);
      e.relative_to_extent = std::max(e.relative_to_extent, error / extent);
    }
    if (!normals.empty()) {
      double n[3], length = 0;
      for (int r = 0; r < 3; ++r) {
        n[r] = m[4 * r] * d.n[0] + m[4 * r + 1] * d.n[1] + m[4 * r + 2] * d.n[2];
        length += n[r] * n[r];
      }
      length = std::sqrt(length);
      for (int r = 0; r < 3; ++r) {
        const double error = std::fabs(normals[3 * v + r] - n[r] / length);
        e.dequantized_normal =
            std::max(e.dequantized_normal, std::isnan(normals[3 * v + r]) ? 1e30 : error);
      }
    }
  }
  if (std::isnan(e.dequantized_position)) e.dequantized_position = 1e30;
  return e;
}

std::string Describe(const Backend& backend, const Case& c) {
  return backend.info().id + " at " + backend.info().simd_target + " " +
         std::string(RestEncodingName(c.encoding)) + " V=" + std::to_string(c.vertices) +
         " B=" + std::to_string(c.influences) + " J=" + std::to_string(c.joints) +
         (c.normals ? " normals" : "");
}

void ExpectWithinBounds(Backend& backend, const Case& c, const Mesh& mesh,
                        const MeshArrays& original, uint64_t seed) {
  auto prepared = backend.Prepare(std::shared_ptr<const Mesh>(&mesh, [](const Mesh*) {}));
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const auto palette = MakeSyntheticPalette(c.joints, seed, 2);
  const Output out = SkinOnce(backend, **prepared, palette, c.normals);
  const std::string what = Describe(backend, c);
  const Errors e = Check(mesh, original, palette, out.positions, out.normals);
  const double tolerance = FloatTolerance(palette, original);
  EXPECT_LE(e.dequantized_position, tolerance) << what << ": against the dequantized input";
  EXPECT_LE(e.dequantized_normal, 1e-5) << what << ": normals against the dequantized input";
  EXPECT_LE(e.over_bound, 1.0) << what << ": against the original input, error / stated bound";
}

class QuantizedRestTargetTest : public ::testing::TestWithParam<std::string> {};

TEST_P(QuantizedRestTargetTest, BothBackendsMatchBothReferencesAtThisTarget) {
  std::vector<std::unique_ptr<Backend>> backends;
  for (int threads : {0, 2}) {  // simd, simd-openmp
    backends.push_back(CreateSimdBackend(threads, GetParam()));
    ASSERT_TRUE(backends.back()->info().available) << backends.back()->info().unavailable_reason;
  }
  uint64_t seed = 1;
  for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
    for (uint32_t b = 1; b <= 8; ++b) {
      for (uint32_t j : {20u, 300u}) {
        for (bool normals : {false, true}) {
          for (uint32_t v : {1u, 3u, 17u, 257u, 1001u}) {
            if (v > TargetCheckMaxVertices()) continue;
            const Case c{v, b, j, normals, encoding};
            const MeshArrays original = RandomMesh(c, ++seed);
            auto mesh = Mesh::Create(original, {.rest_encoding = encoding});
            ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
            for (auto& backend : backends) {
              ExpectWithinBounds(*backend, c, **mesh, original, seed);
              if (HasFailure()) return;
            }
          }
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RunnableHere, QuantizedRestTargetTest,
                         ::testing::ValuesIn(RunnableSimdTargets()),
                         [](const ::testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param;
                         });

// The stated figure: through a rigid joint matrix (a rotation and a translation) the
// position term is at most sqrt(3) * extent / 131070 (half a step per axis, rotated), plus
// float32 rounding. One influence, so that no weight error adds to it (the weights' term
// is checked per vertex above); 100k vertices, any rotation angle.
TEST(QuantizedRestTest, WorstErrorRelativeToExtentOnRigidPalettes) {
  const Case c{100'000, 1, 77, false, RestEncoding::kQuantized16};
  const MeshArrays original = RandomMesh(c, 99);
  auto mesh = Mesh::Create(original, {.rest_encoding = c.encoding});
  ASSERT_TRUE(mesh.ok());
  Backend& backend = BackendById("simd-openmp");
  SKIP_IF_UNAVAILABLE(backend);
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok());
  const auto palette = MakeRigidPalette(c.joints, 99, 1);
  const Output out = SkinOnce(backend, **prepared, palette, false);
  const Errors e = Check(**mesh, original, palette, out.positions, {});
  EXPECT_LE(e.over_bound, 1.0);
  const QuantizedRest& q = *(*mesh)->quantized_rest();
  double extent = 0;
  for (int a = 0; a < 3; ++a) extent = std::max(extent, double{q.scale[a]} * kPositionSteps);
  const double stated = std::sqrt(3.0) / 131070 + FloatTolerance(palette, original) / extent;
  EXPECT_LE(e.relative_to_extent, stated) << "worst error / extent";
  EXPECT_GT(e.relative_to_extent, 1e-7) << "quantization must show somewhere";
  std::printf("worst position error / extent (rigid palette, 100k x 1): %.3g (stated <= %.3g)\n",
              e.relative_to_extent, stated);
}

TEST(QuantizedRestTest, OtherBackendsSkinTheDecodedFloats) {
  const Case c{513, 4, 40, true, RestEncoding::kQuantized8Weights};
  const MeshArrays original = RandomMesh(c, 5);
  auto mesh = Mesh::Create(original, {.rest_encoding = c.encoding});
  ASSERT_TRUE(mesh.ok());
  const auto palette = MakeSyntheticPalette(c.joints, 5, 1);
  for (const std::string& id : ComputingBackendIds()) {
    Backend& backend = BackendById(id);
    if (!backend.info().available) continue;
    auto prepared = backend.Prepare(*mesh);
    ASSERT_TRUE(prepared.ok()) << id << ": " << prepared.status().ToString();
    const Output out = SkinOnce(backend, **prepared, palette, true);
    const Errors e = Check(**mesh, original, palette, out.positions, out.normals);
    EXPECT_LE(e.dequantized_position, FloatTolerance(palette, original)) << id;
    EXPECT_LE(e.dequantized_normal, 1e-5) << id;
  }
}

TEST(QuantizedRestTest, DualQuaternionsOnTheQuantizedStreamAreRefusedWithTheReason) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 10, .joint_count = 8}),
                           {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(mesh.ok());
  Backend& backend = BackendById("simd");
  SKIP_IF_UNAVAILABLE(backend);
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok());
  std::vector<float> positions(30);
  const auto palette = MakeRigidPalette(8, 1, 1);
  const Status s = backend.Skin(
      **prepared,
      {.palette = palette, .positions = positions, .method = SkinningMethod::kDualQuaternion});
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("quantized rest stream"), std::string::npos) << s.message();
}

TEST(QuantizedRestTest, MeshesWithMorphTargetsStayFloat) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 50, .normals = true});
  AddSyntheticMorphTargets({.targets = 2, .fraction = 0.2, .seed = 3}, &arrays);
  auto mesh = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(mesh.status().message().find("rest_encoding quantized16 with 2 morph targets"),
            std::string::npos)
      << mesh.status().message();
}

TEST(QuantizedRestTest, IdsAndBytesSayWhatIsStored) {
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 1000, .influences = 4});
  auto plain = Mesh::Create(arrays).value();
  auto q16 = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16}).value();
  auto again = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16}).value();
  auto q8 = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized8Weights}).value();
  EXPECT_NE(plain->id(), q16->id());
  EXPECT_NE(q16->id(), q8->id());
  EXPECT_EQ(q16->id(), again->id()) << "content ids stay deterministic";
  EXPECT_EQ(plain->quantized_rest(), nullptr);
  EXPECT_EQ(q16->rest_encoding(), RestEncoding::kQuantized16);
  // 77 joints: 8-bit joints. Stored beside the floats: 6 + 4 + 3 * 2 = 16 bytes a vertex.
  EXPECT_EQ(q16->byte_size(), plain->byte_size() + 1000 * 16);
  EXPECT_EQ(q8->byte_size(), plain->byte_size() + 1000 * 13);
  EXPECT_EQ(q16->quantized_rest()->byte_size(), 1000u * 16);
  // What a frame streams per vertex (positions only, B = 4): 40 float, 28 and 25 quantized.
  EXPECT_EQ(StreamedBytesPerVertex(RestEncoding::kFloat32, 4, 77, false), 40.0);
  EXPECT_EQ(StreamedBytesPerVertex(RestEncoding::kQuantized16, 4, 77, false), 28.0);
  EXPECT_EQ(StreamedBytesPerVertex(RestEncoding::kQuantized8Weights, 4, 77, false), 25.0);
}

}  // namespace
}  // namespace skinserve::testing
