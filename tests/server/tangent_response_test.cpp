// Tangents in the answer (SkinRequest.want_tangents) through a real server over loopback
// gRPC and the real client library: every encoding x linear and dual quaternions x with and
// without morph tangent deltas x single and crowd frames x answers sent over gRPC and
// written into a shared-memory region, each tangent against the float64 reference within
// the float32 tolerance plus the bound its encoding states, w exactly the rest's +1 / -1.
// Asking for tangents where they cannot come is refused naming want_tangents.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/tick.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using client::FrameResult;
using client::RegionOutput;
using client::SharedMemoryRegion;

constexpr uint32_t kJoints = 20;
constexpr uint32_t kTargets = 5;

MeshArrays TangentMesh(uint32_t vertices) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                         .influences = 4,
                                         .joint_count = kJoints,
                                         .normals = true,
                                         .tangents = true,
                                         .seed = 12});
  AddSyntheticMorphTargets({.targets = kTargets, .fraction = 0.3, .seed = 12}, &arrays);
  return arrays;
}

// A fresh directory under /dev/shm (real shared memory) as the server's --shm-dir.
class ShmDir {
 public:
  ShmDir() {
    char name[] = "/dev/shm/skinserve-tangent-test-XXXXXX";
    path_ = mkdtemp(name);
  }
  ~ShmDir() { std::filesystem::remove_all(path_); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::vector<float> Palettes(SkinningMethod method, uint32_t instances, uint64_t frame) {
  std::vector<float> palettes;
  for (uint32_t i = 0; i < instances; ++i) {
    const auto one = method == SkinningMethod::kLinear ? MakeSyntheticPalette(kJoints, 3 + i, frame)
                                                       : MakeRigidPalette(kJoints, 3 + i, frame);
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  return palettes;
}

// Every instance's positions and normals (the existing encoded check) and tangents against
// the float64 reference: x y z within 1e-5 (float32, times the morph deltas' magnification)
// plus NormalEncodingError of the encoding; w exactly the reference's, which is +1 or -1.
void ExpectTangentsMatchReference(const Mesh& mesh, const std::vector<float>& palettes,
                                  const FrameResult& result, SkinningMethod method,
                                  std::span<const MorphWeight> morph, const std::string& what) {
  ASSERT_TRUE(result.status.ok()) << what << ": " << result.status.ToString();
  ASSERT_EQ(result.tangents.size(), 4ull * mesh.vertex_count() * result.instances) << what;
  const std::size_t floats = kFloatsPerJoint * mesh.joint_count();
  const double magnification = ReferenceMorphMagnitudes(mesh, morph).tangent_magnification;
  for (uint32_t k = 0; k < result.instances; ++k) {
    const std::span<const float> palette(palettes.data() + k * floats, floats);
    const EncodedDeviation d = CompareEncodedWithReference(
        mesh, palette, result.encoding, result.bounds[k], result.instance_positions(k),
        result.instance_normals(k), method, morph);
    EXPECT_TRUE(d.within_tolerance())
        << what << " instance " << k << ": position ratio " << d.worst_position_ratio
        << ", normal ratio " << d.worst_normal_ratio;
    const ReferenceFrame ref = method == SkinningMethod::kLinear
                                   ? ReferenceSkin(mesh, palette, morph)
                                   : ReferenceSkinDualQuaternion(mesh, palette, morph);
    ASSERT_EQ(ref.tangents.size(), 4ull * mesh.vertex_count()) << what;
    const std::span<const float> got = result.instance_tangents(k);
    double worst_ratio = 0;
    std::size_t worst = 0, wrong_w = 0;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      for (int a = 0; a < 3; ++a) {
        const double r = ref.tangents[4 * v + a];
        const double bound = 1e-5 * magnification + NormalEncodingError(result.encoding, r);
        const double ratio = std::fabs(got[4 * v + a] - r) / bound;  // NaN: fails below
        if (!(ratio <= worst_ratio)) {
          worst_ratio = std::isnan(ratio) ? INFINITY : ratio;
          worst = v;
        }
      }
      const float w = got[4 * v + 3];
      if (!(w == 1.0f || w == -1.0f) || w != ref.tangents[4 * v + 3]) ++wrong_w;
    }
    EXPECT_LE(worst_ratio, 1.0) << what << " instance " << k << ": tangent error / bound "
                                << worst_ratio << " at vertex " << worst;
    EXPECT_EQ(wrong_w, 0u) << what << " instance " << k << ": tangents whose w is not the rest's";
  }
}

TEST(TangentResponseTest, EveryEncodingMethodMorphCrowdAndTransportMatchesTheReference) {
  ShmDir dir;
  server::ServerOptions server_options;
  server_options.shm_dir = dir.path();
  TestServer t(server_options, Transport::kUnixSocket);
  const MeshArrays arrays = TangentMesh(301);
  const auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  ASSERT_TRUE(info->has_tangents());
  const uint32_t most = 3;
  auto region = SharedMemoryRegion::Create(
      SharedMemoryRegion::UniqueKey("tangents"),
      64 + wire::RegionFrameBytes(301, most, VertexEncoding::kFloat32, true, true), dir.path());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_TRUE(t.client->RegisterRegion("tangents", **region).ok());
  const RegionOutput output{.name = "tangents", .region = region->get(), .offset = 64};
  const std::vector<MorphWeight> weights = MakeMorphWeights(kTargets, 3, 12, 1);
  int checked = 0;
  for (VertexEncoding encoding :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
      for (bool morph : {false, true}) {
        for (uint32_t instances : {1u, most}) {
          for (bool shm : {false, true}) {
            const std::string what =
                fmt::format("{} {} {} x{} {}", VertexEncodingName(encoding),
                            method == SkinningMethod::kLinear ? "linear" : "dual-quaternion",
                            morph ? "morphed" : "rest", instances, shm ? "shm" : "grpc");
            const auto palettes = Palettes(method, instances, checked);
            const std::span<const MorphWeight> frame_weights =
                morph ? std::span<const MorphWeight>(weights) : std::span<const MorphWeight>();
            FrameResult result;
            const Status s = t.client->Skin(info->mesh_id(), palettes, checked,
                                            {.backend = "serial",
                                             .want_normals = true,
                                             .want_tangents = true,
                                             .method = method,
                                             .encoding = encoding,
                                             .instances = instances,
                                             .output = shm ? output : RegionOutput{},
                                             .morph_weights = frame_weights},
                                            &result);
            ASSERT_TRUE(s.ok()) << what << ": " << s.ToString();
            ASSERT_EQ(result.in_region(), shm) << what;
            if (shm) {
              EXPECT_EQ(result.region_tangents.size(),
                        EncodedTangentBytes(encoding, 301) * instances)
                  << what;
              ASSERT_TRUE(client::DecodeRegionFrame(&result).ok()) << what;
            }
            ExpectTangentsMatchReference(*mesh, palettes, result, method, frame_weights, what);
            ++checked;
          }
        }
      }
    }
  }
  EXPECT_EQ(checked, 3 * 2 * 2 * 2 * 2);
}

// The OpenCL backends encode float16 and snorm16 on the device (BackendInfo.encoded_outputs)
// and only the encoded bytes come back: every encoding x method x morph x crowd x transport
// through both, against the float64 reference (positions, normals, tangents). As an extra,
// the bytes are the host encoder's: the same frame asked in float32 from the same backend,
// encoded on this side, decodes to the very same floats with the very same box. A value
// float16 cannot hold fails the frame naming the instance and the vertex, as on the host.
TEST(TangentResponseTest, OpenClEncodesOnTheDeviceAndMatchesTheReferenceAndTheHostEncoder) {
  ShmDir dir;
  server::ServerOptions server_options;
  server_options.shm_dir = dir.path();
  TestServer t(server_options,
               Transport::kUnixSocket);  // one OpenCL runtime for both backends: PoCL compiles once
  const MeshArrays arrays = TangentMesh(301);
  const auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const uint32_t most = 3;
  auto region = SharedMemoryRegion::Create(
      SharedMemoryRegion::UniqueKey("device-encoded"),
      64 + wire::RegionFrameBytes(301, most, VertexEncoding::kFloat32, true, true), dir.path());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_TRUE(t.client->RegisterRegion("device-encoded", **region).ok());
  const RegionOutput output{.name = "device-encoded", .region = region->get(), .offset = 64};
  const std::vector<MorphWeight> weights = MakeMorphWeights(kTargets, 3, 12, 1);
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  int checked = 0;
  for (const char* backend : {"opencl", "opencl-zerocopy"}) {
    bool available = false;
    for (const auto& b : backends->backends()) available |= b.id() == backend && b.available();
    ASSERT_TRUE(available) << backend << " (PoCL) must be available for this test";
    for (VertexEncoding encoding : {VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
      for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
        for (bool morph : {false, true}) {
          for (uint32_t instances : {1u, most}) {
            const auto palettes = Palettes(method, instances, checked);
            const std::span<const MorphWeight> frame_weights =
                morph ? std::span<const MorphWeight>(weights) : std::span<const MorphWeight>();
            client::SkinOptions options{.backend = backend,
                                        .want_normals = true,
                                        .want_tangents = true,
                                        .method = method,
                                        .encoding = VertexEncoding::kFloat32,
                                        .instances = instances,
                                        .morph_weights = frame_weights};
            FrameResult floats;  // the backend's float32 answer to the same frame
            Status s = t.client->Skin(info->mesh_id(), palettes, checked, options, &floats);
            ASSERT_TRUE(s.ok()) << s.ToString();
            options.encoding = encoding;
            for (bool shm : {false, true}) {
              const std::string what =
                  fmt::format("{} {} {} {} x{} {}", backend, VertexEncodingName(encoding),
                              method == SkinningMethod::kLinear ? "linear" : "dual-quaternion",
                              morph ? "morphed" : "rest", instances, shm ? "shm" : "grpc");
              options.output = shm ? output : RegionOutput{};
              FrameResult result;
              s = t.client->Skin(info->mesh_id(), palettes, checked, options, &result);
              ASSERT_TRUE(s.ok()) << what << ": " << s.ToString();
              if (shm) {
                ASSERT_TRUE(client::DecodeRegionFrame(&result).ok()) << what;
              }
              ExpectTangentsMatchReference(*mesh, palettes, result, method, frame_weights, what);
              // Extra: the host encoder on the float32 answer gives the same values and box.
              for (uint32_t k = 0; k < instances; ++k) {
                const std::size_t n = 3ull * mesh->vertex_count();
                const std::span<const float> p(floats.positions.data() + k * n, n);
                Bounds box;
                if (encoding == VertexEncoding::kSnorm16) box = ComputeBounds(p).value();
                EXPECT_EQ(result.bounds[k], box) << what << " instance " << k;
                const auto host_roundtrip = [&](std::span<const float> in, const char* field) {
                  std::vector<std::byte> bytes(in.size() * 2);
                  std::vector<float> back(in.size());
                  const bool positions = std::string(field) == "positions";
                  const bool tangents = std::string(field) == "tangents";
                  Status e = positions  ? EncodePositions(encoding, in, box, bytes)
                             : tangents ? EncodeTangents(encoding, in, bytes)
                                        : EncodeNormals(encoding, in, bytes);
                  EXPECT_TRUE(e.ok()) << e.ToString();
                  e = positions  ? DecodePositions(encoding, bytes, box, back)
                      : tangents ? DecodeTangents(encoding, bytes, back)
                                 : DecodeNormals(encoding, bytes, back);
                  EXPECT_TRUE(e.ok()) << e.ToString();
                  return back;
                };
                EXPECT_EQ(host_roundtrip(p, "positions"),
                          std::vector<float>(result.instance_positions(k).begin(),
                                             result.instance_positions(k).end()))
                    << what << " instance " << k;
                EXPECT_EQ(host_roundtrip({floats.normals.data() + k * n, n}, "normals"),
                          std::vector<float>(result.instance_normals(k).begin(),
                                             result.instance_normals(k).end()))
                    << what << " instance " << k;
                const std::size_t nt = 4ull * mesh->vertex_count();
                EXPECT_EQ(host_roundtrip({floats.tangents.data() + k * nt, nt}, "tangents"),
                          std::vector<float>(result.instance_tangents(k).begin(),
                                             result.instance_tangents(k).end()))
                    << what << " instance " << k;
              }
              ++checked;
            }
          }
        }
      }
    }
    // float16 overflow in instance 1 of 2: refused naming instance and vertex.
    auto far = Palettes(SkinningMethod::kLinear, 2, 99);
    for (uint32_t j = 0; j < kJoints; ++j) far[kFloatsPerJoint * (kJoints + j) + 3] = 1e6f;
    FrameResult refused;
    const Status s = t.client->Skin(info->mesh_id(), far, 99,
                                    {.backend = backend,
                                     .want_normals = true,
                                     .want_tangents = true,
                                     .encoding = VertexEncoding::kFloat16,
                                     .instances = 2},
                                    &refused);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << backend << ": " << s.ToString();
    EXPECT_NE(s.message().find("instance 1: positions[vertex 0][x]"), std::string::npos)
        << s.ToString();
    EXPECT_NE(s.message().find("beyond float16's range"), std::string::npos) << s.ToString();
  }
  EXPECT_EQ(checked, 2 * 2 * 2 * 2 * 2 * 2);
}

// A frame of more than one part (1 MiB of vertex data each): the tangents field's framing
// and the client's reading across gRPC's slices, per part, for a single instance and a
// crowd sent one instance's range per part.
// Ticks carry each character's own method and outputs: on every backend that skins
// tangents, one tick mixes linear and dual-quaternion characters, with tangents in float32,
// snorm16 (a crowd of 3, morphed) and float16 (into a shared-memory region), beside a
// character without tangents; each against the float64 reference, unary and streamed.
TEST(TangentResponseTest, TicksMixMethodsAndTangentsPerCharacterOnEveryBackend) {
  ShmDir dir;
  server::ServerOptions server_options;
  server_options.shm_dir = dir.path();
  TestServer t(server_options, Transport::kUnixSocket);
  const MeshArrays arrays = TangentMesh(301);
  const auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const uint64_t slot = wire::RegionFrameBytes(301, 1, VertexEncoding::kFloat16, true, true);
  auto region = SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("tick-tangents"), 2 * slot,
                                           dir.path());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_TRUE(t.client->RegisterRegion("tick-tangents", **region).ok());
  const std::vector<MorphWeight> weights = MakeMorphWeights(kTargets, 3, 12, 1);
  struct Spec {
    SkinningMethod method;
    VertexEncoding encoding;
    uint32_t instances;
    bool tangents, morph, region;
  };
  const std::vector<Spec> specs = {
      {SkinningMethod::kLinear, VertexEncoding::kFloat32, 1, true, true, false},
      {SkinningMethod::kDualQuaternion, VertexEncoding::kSnorm16, 3, true, true, false},
      {SkinningMethod::kDualQuaternion, VertexEncoding::kFloat16, 1, true, false, true},
      {SkinningMethod::kLinear, VertexEncoding::kFloat32, 1, false, false, false},
  };
  // Each character's palettes for tick `frame` (kept for the check), and the tick itself.
  const auto build = [&](const std::string& backend, uint64_t frame, client::Tick* tick,
                         std::vector<std::vector<float>>* palettes) {
    palettes->clear();
    for (std::size_t c = 0; c < specs.size(); ++c) {
      const Spec& spec = specs[c];
      palettes->push_back(Palettes(spec.method, spec.instances, frame + c));
      tick->Add(
          info->mesh_id(), palettes->back(),
          {.backend = backend,
           .want_normals = true,
           .want_tangents = spec.tangents,
           .method = spec.method,
           .encoding = spec.encoding,
           .instances = spec.instances,
           .output = spec.region ? RegionOutput{.name = "tick-tangents", .region = region->get()}
                                 : RegionOutput{},
           .morph_weights = spec.morph ? std::span<const MorphWeight>(weights)
                                       : std::span<const MorphWeight>()});
    }
  };
  const auto check = [&](client::TickResult& result,
                         const std::vector<std::vector<float>>& palettes, const std::string& what) {
    ASSERT_TRUE(result.status.ok()) << what << ": " << result.status.ToString();
    ASSERT_EQ(result.characters.size(), specs.size()) << what;
    for (std::size_t c = 0; c < specs.size(); ++c) {
      const Spec& spec = specs[c];
      FrameResult& r = result.characters[c];
      const std::string who = fmt::format("{}, character {}", what, c);
      ASSERT_TRUE(r.status.ok()) << who << ": " << r.status.ToString();
      ASSERT_EQ(r.in_region(), spec.region) << who;
      ASSERT_TRUE(client::DecodeRegionFrame(&r).ok()) << who;
      const std::span<const MorphWeight> morph =
          spec.morph ? std::span<const MorphWeight>(weights) : std::span<const MorphWeight>();
      if (spec.tangents) {
        ExpectTangentsMatchReference(*mesh, palettes[c], r, spec.method, morph, who);
        continue;
      }
      EXPECT_TRUE(r.tangents.empty()) << who;
      const EncodedDeviation d =
          CompareEncodedWithReference(*mesh, palettes[c], r.encoding, r.bounds[0],
                                      r.instance_positions(0), r.instance_normals(0), spec.method);
      EXPECT_TRUE(d.within_tolerance()) << who << ": position ratio " << d.worst_position_ratio;
    }
  };
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  int ticks = 0;
  for (const auto& b : backends->backends()) {
    // passthrough copies the rest pose: nothing to check against a reference.
    if (!b.available() || !b.tangents() || b.id() == "passthrough") continue;
    SCOPED_TRACE(b.id());
    client::Tick tick;
    tick.set_frame(5);
    std::vector<std::vector<float>> palettes;
    build(b.id(), 5, &tick, &palettes);
    client::TickResult result;
    ASSERT_TRUE(t.client->SkinTick(tick, &result).ok()) << result.status.ToString();
    check(result, palettes, b.id() + " unary");
    std::vector<std::vector<std::vector<float>>> sent(2);
    int answered = 0;
    const Status streamed = client::StreamTicks(
        *t.client, {.first_tick = 0, .ticks = 2, .window = 2, .region_stride = slot},
        [&](uint64_t frame, client::Tick* next) { build(b.id(), 10 + frame, next, &sent[frame]); },
        [&](client::TickResult& r, std::chrono::nanoseconds) {
          check(r, sent[r.frame], fmt::format("{} tick {}", b.id(), r.frame));
          ++answered;
        });
    ASSERT_TRUE(streamed.ok()) << streamed.ToString();
    EXPECT_EQ(answered, 2);
    ++ticks;
  }
  EXPECT_GE(ticks, 4) << "backends that skin tangents";
}

TEST(TangentResponseTest, AFrameOfSeveralPartsCarriesEachPartsTangents) {
  TestServer t;
  const MeshArrays arrays = TangentMesh(30'011);  // > 26214 vertices a part in float32
  const auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  for (VertexEncoding encoding : {VertexEncoding::kFloat32, VertexEncoding::kSnorm16}) {
    for (uint32_t instances : {1u, 2u}) {
      const std::string what =
          fmt::format("{} x{} of 30011 vertices", VertexEncodingName(encoding), instances);
      const auto palettes = Palettes(SkinningMethod::kLinear, instances, 7);
      FrameResult result;
      const Status s = t.client->Skin(info->mesh_id(), palettes, 7,
                                      {.want_normals = true,
                                       .want_tangents = true,
                                       .encoding = encoding,
                                       .instances = instances},
                                      &result);
      ASSERT_TRUE(s.ok()) << what << ": " << s.ToString();
      ExpectTangentsMatchReference(*mesh, palettes, result, SkinningMethod::kLinear, {}, what);
    }
  }
}

TEST(TangentResponseTest, EveryBackendThatSkinsTangentsAnswersThemAndTheOthersRefuse) {
  TestServer t;
  const MeshArrays arrays = TangentMesh(203);
  const auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  const std::vector<MorphWeight> weights = MakeMorphWeights(kTargets, 2, 12, 2);
  int answered = 0;
  for (const auto& backend : backends->backends()) {
    if (!backend.available()) continue;
    const auto palettes = Palettes(SkinningMethod::kLinear, 2, 5);
    FrameResult result;
    const Status s = t.client->Skin(
        info->mesh_id(), palettes, 5,
        {.backend = backend.id(),
         .want_normals = true,
         .want_tangents = true,
         .encoding = VertexEncoding::kFloat16,
         .instances = 2,
         .morph_weights = backend.morph_targets() ? std::span<const MorphWeight>(weights)
                                                  : std::span<const MorphWeight>()},
        &result);
    if (!backend.tangents()) {
      EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << backend.id() << ": " << s.ToString();
      EXPECT_NE(s.message().find("want_tangents"), std::string::npos) << s.ToString();
      EXPECT_NE(s.message().find(backend.id()), std::string::npos) << s.ToString();
      continue;
    }
    if (backend.id() == "passthrough") {  // the rest pose's tangents, whatever the palette
      ASSERT_TRUE(s.ok()) << s.ToString();
      for (std::size_t i = 0; i < arrays.tangents.size(); ++i) {
        ASSERT_EQ(result.tangents[i], HalfToFloat(FloatToHalf(arrays.tangents[i]))) << i;
      }
      continue;
    }
    ASSERT_TRUE(s.ok()) << backend.id() << ": " << s.ToString();
    ExpectTangentsMatchReference(*mesh, palettes, result, SkinningMethod::kLinear,
                                 backend.morph_targets() ? std::span<const MorphWeight>(weights)
                                                         : std::span<const MorphWeight>(),
                                 backend.id());
    ++answered;
  }
  EXPECT_GE(answered, 2) << "serial and simd at least";
}

TEST(TangentResponseTest, AskingWhereTangentsCannotComeIsRefusedNamingWantTangents) {
  ShmDir dir;
  server::ServerOptions server_options;
  server_options.shm_dir = dir.path();
  TestServer t(server_options, Transport::kUnixSocket);
  MeshArrays without = TangentMesh(101);
  without.tangents.clear();
  without.morph_tangent_deltas.clear();
  auto plain = t.client->Upload(without);
  ASSERT_TRUE(plain.ok()) << plain.status().ToString();
  auto with = t.client->Upload(TangentMesh(101));
  ASSERT_TRUE(with.ok()) << with.status().ToString();
  const auto palette = MakeSyntheticPalette(kJoints, 1, 1);
  FrameResult result;

  Status s = t.client->Skin(plain->mesh_id(), palette, 1,
                            {.want_normals = true, .want_tangents = true}, &result);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(
      s.message().find("want_tangents is set but mesh " + plain->mesh_id() + " has no tangents"),
      std::string::npos)
      << s.ToString();

  s = t.client->Skin(with->mesh_id(), palette, 2, {.want_tangents = true}, &result);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("want_tangents is set without want_normals"), std::string::npos)
      << s.ToString();

  // A region with room for positions and normals but not the tangents after them.
  const uint64_t room = wire::RegionFrameBytes(101, 1, VertexEncoding::kFloat32, true);
  auto region =
      SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("small"), room, dir.path());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_TRUE(t.client->RegisterRegion("small", **region).ok());
  const RegionOutput output{.name = "small", .region = region->get(), .offset = 0};
  s = t.client->Skin(with->mesh_id(), palette, 3, {.want_normals = true, .output = output},
                     &result);
  EXPECT_TRUE(s.ok()) << "positions and normals fit: " << s.ToString();
  s = t.client->Skin(with->mesh_id(), palette, 4,
                     {.want_normals = true, .want_tangents = true, .output = output}, &result);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("with normals and tangents"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find(fmt::format("the region holds {} bytes", room)), std::string::npos)
      << s.ToString();

  // The stream still serves.
  s = t.client->Skin(with->mesh_id(), palette, 5, {.want_normals = true, .want_tangents = true},
                     &result);
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(result.tangents.size(), 4u * 101);
}

}  // namespace
}  // namespace skinserve::testing
