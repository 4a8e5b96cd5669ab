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
// refused with their reason; ids and byte sizes. `opencl` and `opencl-zerocopy` read the
// integers on the device (quantized_skinning.cl): checked against both references too, and
// their tangents against the reference on the decoded input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "backend_fixture.h"
#include "quantized_reference.h"
#include "reference_cases.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

std::string Describe(const Backend& backend, const QuantizedCase& c) {
  return backend.info().id + " at " + backend.info().simd_target + " " +
         std::string(RestEncodingName(c.encoding)) + " V=" + std::to_string(c.vertices) +
         " B=" + std::to_string(c.influences) + " J=" + std::to_string(c.joints) +
         (c.normals ? " normals" : "");
}

void ExpectWithinBounds(Backend& backend, const QuantizedCase& c, const Mesh& mesh,
                        const MeshArrays& original, uint64_t seed) {
  auto prepared = backend.Prepare(std::shared_ptr<const Mesh>(&mesh, [](const Mesh*) {}));
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const auto palette = MakeSyntheticPalette(c.joints, seed, 2);
  const Output out = SkinOnce(backend, **prepared, palette, c.normals);
  const std::string what = Describe(backend, c);
  const QuantizedErrors e = CheckQuantized(mesh, original, palette, out.positions, out.normals);
  const double tolerance = FloatTolerance(palette, original);
  EXPECT_LE(e.dequantized_position, tolerance) << what << ": against the dequantized input";
  EXPECT_LE(e.dequantized_normal, 1e-5) << what << ": normals against the dequantized input";
  EXPECT_LE(e.over_bound, 1.0) << what << ": against the original input, error / stated bound";
}

// `simd` and `simd-openmp` (two threads) capped at `target`.
std::vector<std::unique_ptr<Backend>> SimdBackendsAt(const std::string& target) {
  std::vector<std::unique_ptr<Backend>> backends;
  for (int threads : {0, 2}) backends.push_back(CreateSimdBackend(threads, target));
  return backends;
}

class QuantizedRestTargetTest : public ::testing::TestWithParam<std::string> {};

TEST_P(QuantizedRestTargetTest, BothBackendsMatchBothReferencesAtThisTarget) {
  const auto backends = SimdBackendsAt(GetParam());
  for (const auto& backend : backends) {
    ASSERT_TRUE(backend->info().available) << backend->info().unavailable_reason;
  }
  uint64_t seed = 1;
  for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
    for (uint32_t b = 1; b <= 8; ++b) {
      for (uint32_t j : {20u, 300u}) {
        for (bool normals : {false, true}) {
          for (uint32_t v : {1u, 3u, 17u, 257u, 1001u}) {
            if (v > TargetCheckMaxVertices()) continue;
            const QuantizedCase c{v, b, j, normals, encoding};
            const MeshArrays original = RandomQuantizedCaseMesh(c, ++seed);
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

// Tangents from the stream (snorm16 xyz, w +-32767): every output against the float64
// reference on the mesh's float arrays, which hold the values the integers decode to
// (ExpectFrameMatchesReference: CompareWithReference's tolerances, tangents' xyz 1e-5, w
// exact). Both weight widths, 8- and 16-bit joints, influence counts with and without a
// vector's worth of weights, tails around the 256-vertex chunks.
TEST_P(QuantizedRestTargetTest, TangentsFromTheStreamMatchTheReferenceOnTheDecodedInput) {
  const auto backends = SimdBackendsAt(GetParam());
  for (const auto& backend : backends) {
    ASSERT_TRUE(backend->info().available) << backend->info().unavailable_reason;
  }
  uint64_t seed = 700;
  for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
    for (uint32_t b : {1u, 3u, 4u, 8u}) {
      for (uint32_t j : {20u, 300u}) {
        for (uint32_t v : {1u, 5u, 257u, 1001u}) {
          if (v > TargetCheckMaxVertices()) continue;
          ++seed;
          for (auto& backend : backends) {
            ExpectQuantizedTangentsMatchReference(*backend, {v, b, j, true, true}, encoding, seed,
                                                  "at " + backend->info().simd_target);
            if (HasFailure()) return;
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

// `opencl` and `opencl-zerocopy` (PoCL here) read the integers too (quantized_skinning.cl),
// against both references: every influence count, both joint and weight widths, with and
// without normals, vertex counts around the work-group (256 vertices) and the work-item (4).
TEST(QuantizedRestTest, OpenClBackendsReadTheIntegersAndMatchBothReferences) {
  uint64_t seed = 500;
  for (const char* id : {"opencl", "opencl-zerocopy"}) {
    Backend& backend = BackendById(id);
    SKIP_IF_UNAVAILABLE(backend);
    EXPECT_TRUE(backend.info().quantized_rest) << id;
    for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
      for (uint32_t j : {20u, 300u}) {
        for (uint32_t b = 1; b <= 8; ++b) {
          for (bool normals : {false, true}) {
            for (uint32_t v : {1u, 6u, 257u, 1001u}) {
              const QuantizedCase c{v, b, j, normals, encoding};
              const MeshArrays original = RandomQuantizedCaseMesh(c, ++seed);
              auto mesh = Mesh::Create(original, {.rest_encoding = encoding});
              ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
              ExpectWithinBounds(backend, c, **mesh, original, seed);
              if (HasFailure()) return;
            }
          }
        }
      }
    }
  }
}

// The stated figure: through a rigid joint matrix (a rotation and a translation) the
// position term is at most sqrt(3) * extent / 131070 (half a step per axis, rotated), plus
// float32 rounding. One influence, so that no weight error adds to it (the weights' term
// is checked per vertex above); 100k vertices, any rotation angle.
TEST(QuantizedRestTest, WorstErrorRelativeToExtentOnRigidPalettes) {
  const QuantizedCase c{100'000, 1, 77, false, RestEncoding::kQuantized16};
  const MeshArrays original = RandomQuantizedCaseMesh(c, 99);
  auto mesh = Mesh::Create(original, {.rest_encoding = c.encoding});
  ASSERT_TRUE(mesh.ok());
  Backend& backend = BackendById("simd-openmp");
  SKIP_IF_UNAVAILABLE(backend);
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok());
  const auto palette = MakeRigidPalette(c.joints, 99, 1);
  const Output out = SkinOnce(backend, **prepared, palette, false);
  const QuantizedErrors e = CheckQuantized(**mesh, original, palette, out.positions, {});
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
  const QuantizedCase c{513, 4, 40, true, RestEncoding::kQuantized8Weights};
  const MeshArrays original = RandomQuantizedCaseMesh(c, 5);
  auto mesh = Mesh::Create(original, {.rest_encoding = c.encoding});
  ASSERT_TRUE(mesh.ok());
  const auto palette = MakeSyntheticPalette(c.joints, 5, 1);
  for (const std::string& id : ComputingBackendIds()) {
    Backend& backend = BackendById(id);
    if (!backend.info().available) continue;
    auto prepared = backend.Prepare(*mesh);
    ASSERT_TRUE(prepared.ok()) << id << ": " << prepared.status().ToString();
    const Output out = SkinOnce(backend, **prepared, palette, true);
    const QuantizedErrors e = CheckQuantized(**mesh, original, palette, out.positions, out.normals);
    EXPECT_LE(e.dequantized_position, FloatTolerance(palette, original)) << id;
    EXPECT_LE(e.dequantized_normal, 1e-5) << id;
  }
}

// The stream's tangents: within a step of the unit direction, w exactly the handedness;
// the mesh's floats hold what they decode to.
TEST(QuantizedRestTest, TangentsAreStoredAsSnorm16WithTheirHandedness) {
  const MeshArrays original = MakeSyntheticMesh(
      {.vertex_count = 300, .influences = 2, .normals = true, .tangents = true, .seed = 8});
  auto mesh = Mesh::Create(original, {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const QuantizedRest& q = *(*mesh)->quantized_rest();
  ASSERT_EQ(q.tangents.size(), 4u * 300);
  for (std::size_t v = 0; v < 300; ++v) {
    const float* t = &original.tangents[4 * v];
    const double length =
        std::sqrt(double{t[0]} * t[0] + double{t[1]} * t[1] + double{t[2]} * t[2]);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(std::abs(q.tangents[4 * v + a] / 32767.0 - t[a] / length), 0.5 / 32767 + 1e-12)
          << "vertex " << v << " axis " << a;
      EXPECT_EQ((*mesh)->tangents()[4 * v + a],
                static_cast<float>(q.tangents[4 * v + a] / 32767.0));
    }
    EXPECT_EQ(q.tangents[4 * v + 3], t[3] < 0 ? -32767 : 32767) << "vertex " << v;
    EXPECT_EQ((*mesh)->tangents()[4 * v + 3], t[3]) << "vertex " << v;
  }
}

// `opencl` and `opencl-zerocopy` read the stream's tangents too (qskin_tangents_*): every
// output against the float64 reference on the decoded input, as the SIMD loops above
// (tangents' xyz 1e-5, w exact); every influence count, both joint and weight widths,
// vertex counts around the work-group and the work-item.
TEST(QuantizedRestTest, OpenClTangentsFromTheStreamMatchTheReferenceOnTheDecodedInput) {
  uint64_t seed = 800;
  for (const char* id : {"opencl", "opencl-zerocopy"}) {
    Backend& backend = BackendById(id);
    SKIP_IF_UNAVAILABLE(backend);
    for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
      for (uint32_t j : {20u, 300u}) {
        for (uint32_t b = 1; b <= 8; ++b) {
          for (uint32_t v : {1u, 6u, 257u, 1001u}) {
            ExpectQuantizedTangentsMatchReference(backend, {v, b, j, true, true}, encoding, ++seed,
                                                  id);
            if (HasFailure()) return;
          }
        }
      }
    }
  }
}

TEST(QuantizedRestTest, DualQuaternionsOnTheQuantizedStreamAreRefusedWithTheReason) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 10, .joint_count = 8}),
                           {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(mesh.ok());
  // Every backend that reads the integers: the same refusal.
  for (const char* id : {"simd", "opencl", "opencl-zerocopy"}) {
    Backend& backend = BackendById(id);
    if (!backend.info().available) continue;
    auto prepared = backend.Prepare(*mesh);
    ASSERT_TRUE(prepared.ok()) << id;
    std::vector<float> positions(30);
    const auto palette = MakeRigidPalette(8, 1, 1);
    const Status s = backend.Skin(
        **prepared,
        {.palette = palette, .positions = positions, .method = SkinningMethod::kDualQuaternion});
    EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << id;
    EXPECT_NE(s.message().find("quantized rest stream"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(id), std::string::npos) << s.message();
  }
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
  // Tangents: 8 bytes more stored and streamed in (16 float), 16 out.
  const MeshArrays with_tangents =
      MakeSyntheticMesh({.vertex_count = 1000, .influences = 4, .normals = true, .tangents = true});
  auto float_t = Mesh::Create(with_tangents).value();
  auto q16_t = Mesh::Create(with_tangents, {.rest_encoding = RestEncoding::kQuantized16}).value();
  EXPECT_EQ(q16_t->byte_size(), float_t->byte_size() + 1000 * (6 + 6 + 8 + 4 + 6));
  EXPECT_EQ(q16_t->quantized_rest()->byte_size(), 1000u * 30);
  EXPECT_EQ(StreamedBytesPerVertex(RestEncoding::kFloat32, 4, 77, true, true), 96.0);
  EXPECT_EQ(StreamedBytesPerVertex(RestEncoding::kQuantized16, 4, 77, true, true), 70.0);
}

}  // namespace
}  // namespace skinserve::testing
