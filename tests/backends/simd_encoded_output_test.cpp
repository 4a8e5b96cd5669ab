// Encoded output written by the `simd` backends (SkinFrame::encoded, simd_encoded_output.h),
// as the OpenCL backends' tests check theirs (tests/opencl/opencl_encoded_output_test.cpp):
// `simd`, and `simd-openmp` on 1 and 2 threads; every influence count 1..8, positions only,
// with normals, with normals and tangents, vertex counts that end inside a chunk and a thread
// range (1, 7, 257, 1001, 20011); linear and dual-quaternion skinning, morph targets and a
// quantized rest stream. Every frame's bytes must equal the host encoder's on the same
// backend's float32 output (and its box for snorm16), and decode within the float64
// reference's float32 tolerance plus the encoding's stated bound. A value the encoding cannot
// hold fails the frame with exactly the host encoder's error, naming the vertex.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>

#include "backends/simd/simd_encoded_output.h"  // core/engine/src: the fallback counter
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

// A backend and the threads its frames run on: simd (1), simd-openmp on 1 and on 2.
struct Runner {
  std::string name;
  int backend_threads;  // CreateSimdBackend's: 0 for `simd`
  int frame_threads;
};

const std::vector<Runner>& Runners() {
  static const std::vector<Runner> runners = {
      {"simd", 0, 0}, {"simd_openmp_1", 2, 1}, {"simd_openmp_2", 2, 2}};
  return runners;
}

Backend& BackendOf(const Runner& r) {
  static std::unique_ptr<Backend> simd = CreateSimdBackend(0, "");
  static std::unique_ptr<Backend> openmp = CreateSimdBackend(2, "");
  return r.backend_threads == 0 ? *simd : *openmp;
}

struct Outputs {
  bool normals;
  bool tangents;
};

struct FrameInput {
  std::shared_ptr<const Mesh> mesh;
  std::vector<float> palette;
  SkinningMethod method = SkinningMethod::kLinear;
  std::vector<MorphWeight> morph;
};

// The host's way: the backend's float32 frame, then core/encoding (as the server's
// EncodeInstance: box, positions, normals, tangents).
struct Encoded {
  Status status = Status::Ok();
  std::vector<std::byte> positions, normals, tangents;
  Bounds box;
};

Encoded HostEncoded(Backend& backend, const PreparedMesh& prepared, const FrameInput& in,
                    VertexEncoding encoding, Outputs o, int threads) {
  const std::size_t v = in.mesh->vertex_count();
  std::vector<float> p(3 * v), n(o.normals ? 3 * v : 0), t(o.tangents ? 4 * v : 0);
  SkinFrame skin{.palette = in.palette, .positions = p, .normals = n, .tangents = t};
  skin.threads = threads;
  skin.method = in.method;
  skin.morph_weights = in.morph;
  Encoded e;
  EXPECT_TRUE(skin.Validate(*in.mesh).ok());
  if (Status s = backend.Skin(prepared, skin); !s.ok()) {
    e.status = s;
    return e;
  }
  e.positions.resize(EncodedBytes(encoding, v));
  e.normals.resize(o.normals ? e.positions.size() : 0);
  e.tangents.resize(o.tangents ? EncodedTangentBytes(encoding, v) : 0);
  if (QuantizedToBox(encoding)) {
    Result<Bounds> box = ComputeBounds(p);
    if (!box.ok()) {
      e.status = box.status();
      return e;
    }
    e.box = *box;
  }
  e.status = EncodePositions(encoding, p, e.box, e.positions);
  if (e.status.ok() && o.normals) e.status = EncodeNormals(encoding, n, e.normals);
  if (e.status.ok() && o.tangents) e.status = EncodeTangents(encoding, t, e.tangents);
  return e;
}

Encoded BackendEncoded(Backend& backend, const PreparedMesh& prepared, const FrameInput& in,
                       VertexEncoding encoding, Outputs o, int threads,
                       std::span<float> box_scratch = {}) {
  const std::size_t v = in.mesh->vertex_count();
  Encoded e;
  e.positions.assign(EncodedBytes(encoding, v), std::byte{0x55});
  e.normals.assign(o.normals ? e.positions.size() : 0, std::byte{0x55});
  e.tangents.assign(o.tangents ? EncodedTangentBytes(encoding, v) : 0, std::byte{0x55});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  e.box = Bounds{{nan, nan, nan}, {nan, nan, nan}};
  SkinFrame skin{.palette = in.palette};
  skin.threads = threads;
  skin.method = in.method;
  skin.morph_weights = in.morph;
  skin.encoded = {.encoding = encoding,
                  .positions = e.positions,
                  .normals = e.normals,
                  .tangents = e.tangents,
                  .bounds = &e.box,
                  .box_scratch = box_scratch};
  const Status valid = skin.Validate(*in.mesh);
  EXPECT_TRUE(valid.ok()) << valid.ToString();
  e.status = backend.Skin(prepared, skin);
  if (!QuantizedToBox(encoding)) e.box = Bounds{};
  return e;
}

// Bytes and box equal to the host encoder's; decoded within the reference's bound.
void ExpectMatches(Backend& backend, const FrameInput& in, VertexEncoding encoding, Outputs o,
                   int threads, std::span<float> box_scratch = {}) {
  auto prepared = backend.Prepare(in.mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const Encoded host = HostEncoded(backend, **prepared, in, encoding, o, threads);
  ASSERT_TRUE(host.status.ok()) << host.status.ToString();
  const uint64_t fallbacks = simd::HostEncodedFallbacks();
  const Encoded direct = BackendEncoded(backend, **prepared, in, encoding, o, threads, box_scratch);
  ASSERT_TRUE(direct.status.ok()) << direct.status.ToString();
  // Encoded by the loop, not by the error path's host encoder (which would match anyway).
  EXPECT_EQ(simd::HostEncodedFallbacks(), fallbacks) << "the frame went through the host encoder";
  EXPECT_TRUE(direct.positions == host.positions) << "positions differ from the host encoder's";
  EXPECT_TRUE(direct.normals == host.normals) << "normals differ from the host encoder's";
  EXPECT_TRUE(direct.tangents == host.tangents) << "tangents differ from the host encoder's";
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(direct.box.min[a], host.box.min[a]) << "axis " << a;
    EXPECT_EQ(direct.box.max[a], host.box.max[a]) << "axis " << a;
  }
  // Against the float64 reference.
  const std::size_t v = in.mesh->vertex_count();
  std::vector<float> p(3 * v), n(o.normals ? 3 * v : 0), t(o.tangents ? 4 * v : 0);
  ASSERT_TRUE(DecodePositions(encoding, direct.positions, direct.box, p).ok());
  if (o.normals) {
    ASSERT_TRUE(DecodeNormals(encoding, direct.normals, n).ok());
  }
  if (o.tangents) {
    ASSERT_TRUE(DecodeTangents(encoding, direct.tangents, t).ok());
  }
  const EncodedDeviation d = CompareEncodedWithReference(*in.mesh, in.palette, encoding, direct.box,
                                                         p, n, in.method, in.morph);
  EXPECT_TRUE(d.within_tolerance())
      << "position ratio " << d.worst_position_ratio << ", normal ratio " << d.worst_normal_ratio
      << " at vertex " << d.worst_vertex;
  if (o.tangents) {
    const ReferenceFrame reference =
        in.method == SkinningMethod::kDualQuaternion
            ? ReferenceSkinDualQuaternion(*in.mesh, in.palette, in.morph)
            : ReferenceSkin(*in.mesh, in.palette, in.morph);
    EXPECT_EQ(TangentValuesOutsideBound(encoding, t, reference.tangents), 0u)
        << "tangent values outside float32 + the encoding's bound";
  }
}

std::shared_ptr<const Mesh> MakeMesh(uint32_t vertices, uint32_t influences, Outputs o,
                                     uint64_t seed, uint32_t joints = 77) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = vertices,
                                              .influences = influences,
                                              .joint_count = joints,
                                              .normals = o.normals,
                                              .tangents = o.tangents,
                                              .seed = seed}));
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return *mesh;
}

constexpr VertexEncoding kEncodings[] = {VertexEncoding::kFloat16, VertexEncoding::kSnorm16};
constexpr Outputs kOutputs[] = {{false, false}, {true, false}, {true, true}};

class SimdEncodedOutputTest : public ::testing::TestWithParam<Runner> {};

TEST_P(SimdEncodedOutputTest, ListsBothEncodings) {
  Backend& backend = BackendOf(GetParam());
  ASSERT_TRUE(backend.info().available) << backend.info().unavailable_reason;
  for (VertexEncoding encoding : kEncodings) {
    EXPECT_TRUE(backend.info().WritesEncoding(encoding)) << VertexEncodingName(encoding);
  }
}

TEST_P(SimdEncodedOutputTest, EveryInfluenceCountAndTailMatchesTheHostEncoder) {
  Backend& backend = BackendOf(GetParam());
  for (uint32_t b = 1; b <= 8; ++b) {
    for (uint32_t v : {1u, 7u, 257u, 1001u}) {
      for (Outputs o : kOutputs) {
        FrameInput in{.mesh = MakeMesh(v, b, o, 11 * v + b)};
        in.palette = MakeSyntheticPalette(77, v + b, 3);
        for (VertexEncoding encoding : kEncodings) {
          SCOPED_TRACE(::testing::Message()
                       << VertexEncodingName(encoding) << " B " << b << " V " << v
                       << (o.tangents ? " normals+tangents" : (o.normals ? " normals" : "")));
          ExpectMatches(backend, in, encoding, o, GetParam().frame_threads);
        }
      }
    }
  }
}

// Many chunks, a thread seam off the chunk grid, 16-bit joints, and both methods.
TEST_P(SimdEncodedOutputTest, LargeFramesAndDualQuaternionsMatchTheHostEncoder) {
  Backend& backend = BackendOf(GetParam());
  for (uint32_t joints : {77u, 300u}) {
    for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
      FrameInput in{.mesh = MakeMesh(20011, 4, {true, true}, joints, joints), .method = method};
      in.palette = method == SkinningMethod::kDualQuaternion ? MakeRigidPalette(joints, 5, 1)
                                                             : MakeSyntheticPalette(joints, 5, 1);
      for (VertexEncoding encoding : kEncodings) {
        for (Outputs o : kOutputs) {
          SCOPED_TRACE(::testing::Message() << VertexEncodingName(encoding) << " J " << joints
                                            << " " << MethodName(method) << " normals " << o.normals
                                            << " tangents " << o.tangents);
          ExpectMatches(backend, in, encoding, o, GetParam().frame_threads);
        }
      }
    }
  }
}

TEST_P(SimdEncodedOutputTest, MorphTargetsMatchTheHostEncoder) {
  Backend& backend = BackendOf(GetParam());
  for (uint32_t v : {7u, 5003u}) {
    MeshArrays arrays = MakeSyntheticMesh({.vertex_count = v,
                                           .influences = 3,
                                           .joint_count = 33,
                                           .normals = true,
                                           .tangents = true,
                                           .seed = v});
    AddSyntheticMorphTargets({.targets = 24, .fraction = 0.2, .seed = v}, &arrays);
    auto mesh = Mesh::Create(arrays);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    FrameInput in{.mesh = *mesh, .palette = MakeSyntheticPalette(33, v, 2)};
    in.morph = MakeMorphWeights(24, 6, v, 2);
    for (VertexEncoding encoding : kEncodings) {
      SCOPED_TRACE(::testing::Message() << VertexEncodingName(encoding) << " V " << v);
      ExpectMatches(backend, in, encoding, {true, true}, GetParam().frame_threads);
    }
  }
}

TEST_P(SimdEncodedOutputTest, AQuantizedMeshMatchesTheHostEncoder) {
  Backend& backend = BackendOf(GetParam());
  for (uint32_t b : {1u, 4u, 7u}) {
    auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 3001,
                                                .influences = b,
                                                .joint_count = 77,
                                                .normals = true,
                                                .seed = 31 + b}),
                             {.rest_encoding = RestEncoding::kQuantized16});
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    FrameInput in{.mesh = *mesh, .palette = MakeSyntheticPalette(77, 31, 4)};
    for (VertexEncoding encoding : kEncodings) {
      for (Outputs o : {Outputs{false, false}, Outputs{true, false}}) {
        SCOPED_TRACE(::testing::Message()
                     << VertexEncodingName(encoding) << " B " << b << " normals " << o.normals);
        ExpectMatches(backend, in, encoding, o, GetParam().frame_threads);
      }
    }
  }
}

// Every joint maps x to 0: snorm16's empty axis writes q = 0 and the box's x is [0, 0].
TEST_P(SimdEncodedOutputTest, AnEmptyAxisOfTheBoxEncodesAsZero) {
  Backend& backend = BackendOf(GetParam());
  FrameInput in{.mesh = MakeMesh(1000, 2, {false, false}, 8)};
  in.palette = MakeSyntheticPalette(77, 8, 1);
  for (uint32_t j = 0; j < 77; ++j) {
    for (int c = 0; c < 4; ++c) in.palette[12 * j + c] = 0.0f;  // row 0: x = 0
  }
  ExpectMatches(backend, in, VertexEncoding::kSnorm16, {false, false}, GetParam().frame_threads);
}

// snorm16 with the caller's box_scratch (the server's frame job gives one, to count it in its
// in-flight budget): the same bytes, and the scratch holds the skinned positions (within the
// float64 reference's float32 tolerance), so the loop used it instead of its thread's buffer.
TEST_P(SimdEncodedOutputTest, Snorm16KeepsItsPositionsInTheCallersBoxScratch) {
  Backend& backend = BackendOf(GetParam());
  EXPECT_TRUE(backend.info().encoded_box_scratch);
  for (uint32_t v : {1u, 1001u, 20011u}) {
    for (Outputs o : {Outputs{false, false}, Outputs{true, false}}) {
      SCOPED_TRACE(::testing::Message() << "V " << v << " normals " << o.normals);
      FrameInput in{.mesh = MakeMesh(v, 4, o, 5 * v)};
      in.palette = MakeSyntheticPalette(77, v, 2);
      std::vector<float> scratch(3 * v, std::numeric_limits<float>::quiet_NaN());
      ExpectMatches(backend, in, VertexEncoding::kSnorm16, o, GetParam().frame_threads, scratch);
      const Deviation d = CompareWithReference(*in.mesh, in.palette, scratch, {});
      EXPECT_TRUE(d.within_tolerance()) << "box_scratch is not the skinned positions: worst "
                                        << d.max_position_error << " at vertex " << d.worst_vertex;
    }
  }
}

// The first vertex (in vertex order) of the joint that overflows, past the first chunks and
// in the second thread's range: the frame fails with the host encoder's error, word for word.
TEST_P(SimdEncodedOutputTest, AValueTheEncodingCannotHoldFailsNamingTheVertex) {
  Backend& backend = BackendOf(GetParam());
  constexpr uint32_t kVertices = 2000, kJoints = 77;
  auto mesh = MakeMesh(kVertices, 1, {true, true}, 9, kJoints);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const uint32_t joint = mesh->joints()[1500];  // B = 1: one joint per vertex
  uint32_t first = 0;
  while (mesh->joints()[first] != joint) ++first;
  struct Case {
    VertexEncoding encoding;
    float scale;  // the joint's row y: y' = scale * (x + y + z + 1), past float's range at 3e38
    const char* says;
  };
  for (const Case& c : {Case{VertexEncoding::kFloat16, 1e6f, "beyond float16's range"},
                        Case{VertexEncoding::kSnorm16, 3e38f, "is not finite"}}) {
    SCOPED_TRACE(::testing::Message() << VertexEncodingName(c.encoding) << " " << c.scale);
    FrameInput in{.mesh = mesh, .palette = MakeSyntheticPalette(kJoints, 9, 2)};
    for (int col = 0; col < 4; ++col) in.palette[12 * joint + 4 + col] = c.scale;
    const Encoded host =
        HostEncoded(backend, **prepared, in, c.encoding, {true, true}, GetParam().frame_threads);
    ASSERT_FALSE(host.status.ok());
    const uint64_t fallbacks = simd::HostEncodedFallbacks();
    const Encoded direct =
        BackendEncoded(backend, **prepared, in, c.encoding, {true, true}, GetParam().frame_threads);
    EXPECT_EQ(simd::HostEncodedFallbacks(), fallbacks + 1);
    EXPECT_EQ(direct.status.code(), StatusCode::kInvalidArgument) << direct.status.ToString();
    EXPECT_EQ(direct.status.message(), host.status.message());
    EXPECT_NE(direct.status.message().find(c.says), std::string::npos) << direct.status.ToString();
    // 1e6: every vertex of the joint overflows, the first is named; 3e38: the first whose
    // x + y + z + 1 is positive (the host's message, compared above).
    const std::string named =
        c.scale == 1e6f ? "positions[vertex " + std::to_string(first) + "][y]" : "][y]";
    EXPECT_NE(direct.status.message().find(named), std::string::npos)
        << direct.status.ToString() << " (expected " << named << ")";
  }
}

INSTANTIATE_TEST_SUITE_P(Simd, SimdEncodedOutputTest, ::testing::ValuesIn(Runners()),
                         [](const ::testing::TestParamInfo<Runner>& param) {
                           return param.param.name;
                         });

}  // namespace
}  // namespace skinserve::testing
