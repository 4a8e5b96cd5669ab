// Morph targets through a real server over loopback gRPC: a mesh uploaded with sparse
// targets (chunked, like every array) reports them; frames with sparse weights come back
// matching the float64 reference (which morphs in double before skinning) on every backend
// that applies them (all but passthrough; OpenCL on the device), unary, streamed and as a
// crowd (whose instances share the request's weights), in float32 and snorm16, linear and
// dual quaternions on OpenCL, morphed frames alternating with plain ones. Bad weights (on
// any backend, OpenCL included) are INVALID_ARGUMENT naming the field and the entry, a
// backend without morph targets is FAILED_PRECONDITION naming it, and neither ends the
// stream. Bad targets on upload are refused naming the field; their bytes are charged to
// --upload-budget-mb. Tolerance: CompareWithReference's with morphs (float32), plus the
// snorm16 step for the encoded frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "expect_status.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr uint32_t kJoints = 40;
constexpr uint32_t kTargets = 16;

MeshArrays MorphArrays(uint32_t vertices = 3001) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                         .influences = 4,
                                         .joint_count = kJoints,
                                         .normals = true,
                                         .seed = 11});
  AddSyntheticMorphTargets({.targets = kTargets, .fraction = 0.1, .seed = 11}, &arrays);
  return arrays;
}

void ExpectMatches(const Mesh& mesh, std::span<const float> palette,
                   std::span<const MorphWeight> weights, std::span<const float> positions,
                   std::span<const float> normals, const std::string& what) {
  const Deviation d =
      CompareWithReference(mesh, palette, positions, normals, SkinningMethod::kLinear, weights);
  EXPECT_TRUE(d.within_tolerance())
      << what << ": position error " << d.max_position_error << " (tolerance "
      << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
      << d.normal_tolerance << ")";
}

TEST(MorphServiceTest, UploadReportsTargetsAndBackendsSayWhoAppliesThem) {
  TestServer t;
  const MeshArrays arrays = MorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->morph_target_count(), kTargets);
  const auto mesh = Mesh::Create(arrays).value();
  EXPECT_EQ(info->mesh_id(), mesh->id());
  EXPECT_EQ(info->bytes(), mesh->byte_size());
  auto got = t.client->GetMesh(info->mesh_id());
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->morph_target_count(), kTargets);
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  for (const auto& b : list->backends()) {
    EXPECT_EQ(b.morph_targets(), b.id() != "passthrough" && b.available()) << b.id();
  }
}

TEST(MorphServiceTest, FramesMatchTheReferenceOnEveryBackendThatAppliesThem) {
  TestServer t;
  const MeshArrays arrays = MorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int checked = 0;
  std::vector<std::string> ids;
  for (const auto& b : list->backends()) {
    if (!b.morph_targets()) continue;
    ids.push_back(b.id());
    for (uint64_t frame = 0; frame < 3; ++frame) {
      // 4 active, none, 16 active.
      const std::vector<MorphWeight> weights =
          frame == 1 ? std::vector<MorphWeight>()
                     : MakeMorphWeights(kTargets, frame == 0 ? 4 : kTargets, 5, frame);
      const auto palette = MakeSyntheticPalette(kJoints, 5, frame);
      client::FrameResult result;
      client::SkinOptions options{.backend = b.id(), .want_normals = true};
      options.morph_weights = weights;
      Status s = t.client->Skin(info->mesh_id(), palette, frame, options, &result);
      ASSERT_TRUE(s.ok()) << b.id() << ": " << s.ToString();
      ExpectMatches(*mesh, palette, weights, result.positions, result.normals,
                    b.id() + " frame " + std::to_string(frame));
      ++checked;
    }
    // A crowd of 3: each instance its own palette, all the request's weights.
    const auto weights = MakeMorphWeights(kTargets, 4, 6, 0);
    std::vector<float> palettes;
    for (uint64_t i = 0; i < 3; ++i) {
      const auto p = MakeSyntheticPalette(kJoints, 6, i);
      palettes.insert(palettes.end(), p.begin(), p.end());
    }
    client::FrameResult result;
    client::SkinOptions options{.backend = b.id(), .want_normals = true, .instances = 3};
    options.morph_weights = weights;
    Status s = t.client->Skin(info->mesh_id(), palettes, 9, options, &result);
    ASSERT_TRUE(s.ok()) << b.id() << ": " << s.ToString();
    const std::size_t n = 3ull * mesh->vertex_count();
    for (std::size_t i = 0; i < 3; ++i) {
      ExpectMatches(*mesh, std::span<const float>(palettes).subspan(i * 12 * kJoints, 12 * kJoints),
                    weights, std::span<const float>(result.positions).subspan(i * n, n),
                    std::span<const float>(result.normals).subspan(i * n, n),
                    b.id() + " crowd instance " + std::to_string(i));
    }
  }
  EXPECT_GE(checked, 3 * 4) << "serial, openmp, simd and simd-openmp at least";
  for (const auto& b : list->backends()) {
    if (b.id().starts_with("opencl") && b.available()) {
      EXPECT_NE(std::find(ids.begin(), ids.end(), b.id()), ids.end()) << b.id() << " not checked";
    }
  }
}

// Streams on the OpenCL backends, linear and dual quaternions: morphed frames (1 to all 16
// targets active) alternate with frames without weights and frames with zero weights only,
// each matching its own reference (a plain frame after a morphed one is the plain shape).
TEST(MorphServiceTest, OpenClStreamsMorphedAndPlainFramesInBothMethods) {
  TestServer t;
  const MeshArrays arrays = MorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  auto weights_of = [](uint64_t f) {
    if (f % 4 == 1) return std::vector<MorphWeight>{{2, 0.0f}};  // zero weights only
    if (f % 2 == 1) return std::vector<MorphWeight>();
    return MakeMorphWeights(kTargets, f % 8 == 0 ? kTargets : 1 + static_cast<uint32_t>(f % 5), 12,
                            f);
  };
  for (const char* id : {"opencl", "opencl-zerocopy"}) {
    const auto found = std::find_if(list->backends().begin(), list->backends().end(),
                                    [&](const auto& b) { return b.id() == id; });
    ASSERT_NE(found, list->backends().end()) << id;
    if (!found->available()) GTEST_SKIP() << id << " unavailable: " << found->unavailable_reason();
    for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
      auto palette_of = [method](uint64_t f) {
        return method == SkinningMethod::kDualQuaternion ? MakeRigidPalette(kJoints, 12, f)
                                                         : MakeSyntheticPalette(kJoints, 12, f);
      };
      std::vector<MorphWeight> held;
      client::StreamOptions options{.mesh_id = info->mesh_id(),
                                    .backend = id,
                                    .want_normals = true,
                                    .method = method,
                                    .frames = 12};
      options.morph_weights = [&](uint64_t f) {
        held = weights_of(f);
        return std::span<const MorphWeight>(held);
      };
      uint64_t checked = 0;
      const std::string what = std::string(id) + " " + std::string(MethodName(method));
      Status streamed = client::StreamFrames(
          *t.client, options, palette_of, [&](client::FrameResult& r, std::chrono::nanoseconds) {
            ASSERT_TRUE(r.status.ok()) << what << ": " << r.status.ToString();
            const auto palette = palette_of(r.frame);
            const auto weights = weights_of(r.frame);
            const Deviation d =
                CompareWithReference(*mesh, palette, r.positions, r.normals, method, weights);
            EXPECT_TRUE(d.within_tolerance())
                << what << " frame " << r.frame << ": position error " << d.max_position_error
                << " (tolerance " << d.position_tolerance << "), normal error "
                << d.max_normal_error << " (tolerance " << d.normal_tolerance << ")";
            ++checked;
          });
      EXPECT_TRUE(streamed.ok()) << what << ": " << streamed.ToString();
      EXPECT_EQ(checked, 12u) << what;
    }
    // Bad weights get the engine's errors, as on every backend.
    client::FrameResult result;
    client::SkinOptions options{.backend = id};
    const std::vector<MorphWeight> unknown = {{1, 0.5f}, {kTargets, 1.0f}};
    options.morph_weights = unknown;
    ExpectStatus(
        t.client->Skin(info->mesh_id(), MakeSyntheticPalette(kJoints, 12, 0), 0, options, &result),
        StatusCode::kInvalidArgument,
        "morph_weights[1]: target 16 is not below the mesh's morph_target_count 16");
    const std::vector<MorphWeight> nan = {{3, std::numeric_limits<float>::quiet_NaN()}};
    options.morph_weights = nan;
    ExpectStatus(
        t.client->Skin(info->mesh_id(), MakeSyntheticPalette(kJoints, 12, 0), 0, options, &result),
        StatusCode::kInvalidArgument, "morph_weights[0]: weight nan of target 3 must be finite");
  }
}

TEST(MorphServiceTest, StreamedFramesCarryTheirOwnWeights) {
  TestServer t;
  const MeshArrays arrays = MorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  // Even frames: 4 active targets; odd frames: none.
  auto weights_of = [](uint64_t f) {
    return f % 2 == 0 ? MakeMorphWeights(kTargets, 4, 7, f) : std::vector<MorphWeight>();
  };
  std::vector<MorphWeight> held;
  client::StreamOptions options{
      .mesh_id = info->mesh_id(), .backend = "simd-openmp", .want_normals = true, .frames = 8};
  options.morph_weights = [&](uint64_t f) {
    held = weights_of(f);
    return std::span<const MorphWeight>(held);
  };
  uint64_t checked = 0;
  Status streamed = client::StreamFrames(
      *t.client, options, [](uint64_t f) { return MakeSyntheticPalette(kJoints, 7, f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        ExpectMatches(*mesh, MakeSyntheticPalette(kJoints, 7, r.frame), weights_of(r.frame),
                      r.positions, r.normals, "streamed frame " + std::to_string(r.frame));
        ++checked;
      });
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(checked, 8u);
}

TEST(MorphServiceTest, Snorm16FramesMatchWithinTheQuantizationStep) {
  TestServer t;
  const MeshArrays arrays = MorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  const auto weights = MakeMorphWeights(kTargets, 4, 8, 0);
  const auto palette = MakeSyntheticPalette(kJoints, 8, 0);
  client::FrameResult result;
  client::SkinOptions options{
      .backend = "simd", .want_normals = false, .encoding = VertexEncoding::kSnorm16};
  options.morph_weights = weights;
  ASSERT_TRUE(t.client->Skin(info->mesh_id(), palette, 0, options, &result).ok());
  const ReferenceFrame ref = ReferenceSkin(*mesh, palette, weights);
  const Bounds& box = result.bounds.at(0);
  const double step[3] = {(double{box.max[0]} - box.min[0]) / 65534,
                          (double{box.max[1]} - box.min[1]) / 65534,
                          (double{box.max[2]} - box.min[2]) / 65534};
  for (std::size_t i = 0; i < ref.positions.size(); ++i) {
    ASSERT_NEAR(result.positions[i], ref.positions[i], step[i % 3] + 1e-4) << "value " << i;
  }
}

TEST(MorphServiceTest, BadWeightsAndBackendsAreRefusedWithoutEndingTheStream) {
  TestServer t;
  const MeshArrays arrays = MorphArrays(500);
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  grpc::ClientContext context;
  auto stream = t.client->stub().StreamSkin(&context);
  auto send = [&](uint64_t frame, const std::string& backend, std::vector<uint32_t> targets,
                  std::vector<float> weights, client::FrameResult* out = nullptr) {
    v1::SkinRequest request;
    request.set_mesh_id(info->mesh_id());
    request.set_backend(backend);
    request.set_frame(frame);
    request.set_palette(wire::EncodeFloats(MakeSyntheticPalette(kJoints, 2, frame)));
    for (uint32_t target : targets) request.add_morph_targets(target);
    for (float w : weights) request.add_morph_weights(w);
    EXPECT_TRUE(stream->Write(request));
    client::FrameResult r;
    client::FrameAssembler assembler;
    v1::SkinResponse part;
    while (stream->Read(&part)) {
      if (assembler.Add(part, &r)) break;
    }
    if (out != nullptr) *out = r;
    return r.status;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ExpectStatus(send(1, "serial", {2, kTargets}, {0.5f, 1}), StatusCode::kInvalidArgument,
               "morph_weights[1]: target 16 is not below the mesh's morph_target_count 16");
  ExpectStatus(send(2, "simd", {3}, {nan}), StatusCode::kInvalidArgument,
               "morph_weights[0]: weight nan of target 3 must be finite");
  ExpectStatus(send(3, "simd", {3}, {std::numeric_limits<float>::infinity()}),
               StatusCode::kInvalidArgument, "weight inf of target 3");
  ExpectStatus(send(4, "openmp", {3, 4, 3}, {1, 1, 1}), StatusCode::kInvalidArgument,
               "morph_weights[2]: target 3 is listed twice");
  ExpectStatus(send(5, "serial", {3, 4}, {1}), StatusCode::kInvalidArgument,
               "morph_targets holds 2 entries but morph_weights 1");
  ExpectStatus(send(6, "passthrough", {3}, {1}), StatusCode::kFailedPrecondition,
               "backend 'passthrough' does not apply morph targets");
  // Zero weights only: any backend, the rest shape.
  EXPECT_TRUE(send(7, "passthrough", {3}, {0}).ok());
  // And the stream goes on: the next frame is skinned and right.
  client::FrameResult good;
  ASSERT_TRUE(send(8, "sse-openmp", {3, 0}, {1.25f, -0.5f}, &good).ok());
  const std::vector<MorphWeight> weights = {{3, 1.25f}, {0, -0.5f}};
  ExpectMatches(*mesh, MakeSyntheticPalette(kJoints, 2, 8), weights, good.positions, {},
                "after the refusals");
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

// A raw upload of `arrays` with `edit` applied to its header first.
grpc::Status RawUpload(client::SkinClient& client, const MeshArrays& arrays,
                       const std::function<void(v1::MeshHeader*)>& edit = {}) {
  grpc::ClientContext context;
  v1::MeshInfo info;
  auto writer = client.stub().UploadMesh(&context, &info);
  v1::UploadMeshRequest header;
  v1::MeshHeader* h = header.mutable_header();
  h->set_vertex_count(arrays.vertex_count);
  h->set_influences(arrays.influences);
  h->set_joint_count(arrays.joint_count);
  h->set_has_normals(!arrays.normals.empty());
  for (uint32_t size : arrays.morph_target_sizes) h->add_morph_target_sizes(size);
  h->set_morph_normals(!arrays.morph_normal_deltas.empty());
  if (edit) edit(h);
  bool sending = writer->Write(header);
  // Chunks of 1 MiB; offsets count values of `value_size` bytes.
  auto send = [&](v1::MeshArray kind, const void* data, std::size_t bytes,
                  std::size_t value_size = 4) {
    for (std::size_t offset = 0; sending && offset < bytes; offset += 1 << 20) {
      const std::size_t n = std::min<std::size_t>(1 << 20, bytes - offset);
      v1::UploadMeshRequest chunk;
      chunk.mutable_chunk()->set_array(kind);
      chunk.mutable_chunk()->set_offset(offset / value_size);
      chunk.mutable_chunk()->set_data(static_cast<const char*>(data) + offset, n);
      sending = writer->Write(chunk);
    }
  };
  send(v1::MESH_ARRAY_POSITIONS, arrays.positions.data(), 4 * arrays.positions.size());
  send(v1::MESH_ARRAY_NORMALS, arrays.normals.data(), 4 * arrays.normals.size());
  send(v1::MESH_ARRAY_JOINTS, arrays.joints.data(), 2 * arrays.joints.size(), 2);
  send(v1::MESH_ARRAY_WEIGHTS, arrays.weights.data(), 4 * arrays.weights.size());
  send(v1::MESH_ARRAY_MORPH_INDICES, arrays.morph_indices.data(), 4 * arrays.morph_indices.size());
  send(v1::MESH_ARRAY_MORPH_POSITION_DELTAS, arrays.morph_position_deltas.data(),
       4 * arrays.morph_position_deltas.size());
  send(v1::MESH_ARRAY_MORPH_NORMAL_DELTAS, arrays.morph_normal_deltas.data(),
       4 * arrays.morph_normal_deltas.size());
  if (sending) writer->WritesDone();
  return writer->Finish();
}

TEST(MorphServiceTest, BadTargetsAreRefusedOnUploadNamingTheField) {
  TestServer t;
  MeshArrays arrays = MorphArrays(500);
  ASSERT_TRUE(RawUpload(*t.client, arrays).ok()) << "the raw upload itself works";
  MeshArrays bad = arrays;
  bad.morph_indices[1] = bad.morph_indices[0];
  Status s = wire::FromGrpc(RawUpload(*t.client, bad));
  ExpectStatus(s, StatusCode::kInvalidArgument, "morph_indices[target 0, delta 1]");
  bad = arrays;
  bad.morph_position_deltas[5] = std::numeric_limits<float>::quiet_NaN();
  ExpectStatus(wire::FromGrpc(RawUpload(*t.client, bad)), StatusCode::kInvalidArgument,
               "morph_position_deltas[target 0, delta 1].z = nan");
  ExpectStatus(wire::FromGrpc(RawUpload(*t.client, arrays,
                                        [](v1::MeshHeader* h) { h->set_has_normals(false); })),
               StatusCode::kInvalidArgument,
               "morph normal deltas were declared but the mesh has no normals");
  ExpectStatus(
      wire::FromGrpc(RawUpload(*t.client, arrays,
                               [](v1::MeshHeader* h) { h->set_morph_target_sizes(0, 501); })),
      StatusCode::kInvalidArgument, "morph_target_sizes[0] = 501 exceeds vertex_count 500");
  ExpectStatus(wire::FromGrpc(RawUpload(*t.client, arrays,
                                        [](v1::MeshHeader* h) {
                                          for (int i = 0; i < 1100; ++i)
                                            h->add_morph_target_sizes(0);
                                        })),
               StatusCode::kResourceExhausted, "over the limit of 1024 targets per mesh");
}

TEST(MorphServiceTest, DeltasAreChargedToTheUploadBudget) {
  server::ServerOptions options;
  options.upload_budget_mb = 2;
  TestServer t(options);
  // 50k vertices, B = 1, no normals: 0.9 MB of vertex arrays; 4 targets over every vertex:
  // 0.8 MB of indices and 2.4 MB of position deltas, beyond the 2 MB budget together.
  MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 50'000, .influences = 1, .joint_count = 4, .normals = false, .seed = 4});
  AddSyntheticMorphTargets({.targets = 4, .fraction = 1.0, .seed = 4}, &arrays);
  const Status s = wire::FromGrpc(RawUpload(*t.client, arrays));
  ExpectStatus(s, StatusCode::kResourceExhausted, "morph_position_deltas chunk at offset");
  EXPECT_NE(s.message().find("--upload-budget-mb"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace skinserve::testing
