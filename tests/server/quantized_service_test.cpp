// The quantized rest stream through a real server over loopback gRPC: an upload with
// MeshHeader.rest_encoding (SkinClient::Upload's UploadOptions, or the raw field) is stored
// quantized (MeshInfo says so, its id and bytes are the quantized mesh's), frames on `simd` and
// `simd-openmp` (which read the integers) and on `serial` (which reads the decoded floats) match
// the float64 reference on the decoded input, unary and streamed; an unknown encoding, quantizing a
// mesh with morph targets and dual quaternions on the quantized `simd` stream are refused naming
// the reason. Tolerance: CompareWithReference's (float32 rounding, 1e-5 * (1 + S)). The bound
// against the original float input is tested per target in quantized_rest_test.cpp. `opencl`
// (which reads the integers on the device) gets the same checks. A mesh's tangents travel in
// the stream: `simd` skins them, `opencl` refuses them naming who does.
#include <gtest/gtest.h>

#include <algorithm>

#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr uint32_t kJoints = 40;

v1::UploadMeshRequest Chunk(v1::MeshArray array, const void* data, std::size_t bytes) {
  v1::UploadMeshRequest m;
  m.mutable_chunk()->set_array(array);
  m.mutable_chunk()->set_offset(0);
  m.mutable_chunk()->set_data(static_cast<const char*>(data), bytes);
  return m;
}

// Uploads `arrays` (one chunk per array) with `encoding` as the raw wire has it.
Result<v1::MeshInfo> Upload(client::SkinClient& c, const MeshArrays& arrays, int encoding,
                            std::vector<uint32_t> morph_sizes = {}) {
  std::vector<v1::UploadMeshRequest> messages(1);
  v1::MeshHeader* h = messages[0].mutable_header();
  h->set_vertex_count(arrays.vertex_count);
  h->set_influences(arrays.influences);
  h->set_joint_count(arrays.joint_count);
  h->set_has_normals(!arrays.normals.empty());
  h->set_rest_encoding(static_cast<v1::RestEncoding>(encoding));
  for (uint32_t size : morph_sizes) h->add_morph_target_sizes(size);
  messages.push_back(
      Chunk(v1::MESH_ARRAY_POSITIONS, arrays.positions.data(), arrays.positions.size() * 4));
  if (!arrays.normals.empty()) {
    messages.push_back(
        Chunk(v1::MESH_ARRAY_NORMALS, arrays.normals.data(), arrays.normals.size() * 4));
  }
  messages.push_back(Chunk(v1::MESH_ARRAY_JOINTS, arrays.joints.data(), arrays.joints.size() * 2));
  messages.push_back(
      Chunk(v1::MESH_ARRAY_WEIGHTS, arrays.weights.data(), arrays.weights.size() * 4));
  return RawUploadMesh(c, messages);
}

MeshArrays Arrays() {
  return MakeSyntheticMesh(
      {.vertex_count = 3001, .influences = 4, .joint_count = kJoints, .normals = true, .seed = 21});
}

void ExpectMatches(const Mesh& mesh, std::span<const float> palette,
                   std::span<const float> positions, std::span<const float> normals,
                   const std::string& what) {
  const Deviation d = CompareWithReference(mesh, palette, positions, normals);
  EXPECT_TRUE(d.within_tolerance())
      << what << ": position error " << d.max_position_error << " (tolerance "
      << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
      << d.normal_tolerance << ")";
}

TEST(QuantizedServiceTest, UploadedQuantizedSkinsOnSimdLikeTheDecodedReference) {
  TestServer t;
  const MeshArrays arrays = Arrays();
  for (auto [wire, encoding] :
       {std::pair{v1::REST_ENCODING_QUANTIZED16, RestEncoding::kQuantized16},
        std::pair{v1::REST_ENCODING_QUANTIZED8_WEIGHTS, RestEncoding::kQuantized8Weights}}) {
    // Through the client library, as users ask for it.
    auto info = t.client->Upload(arrays, {.rest_encoding = encoding});
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    const auto mesh = Mesh::Create(arrays, {.rest_encoding = encoding}).value();
    EXPECT_EQ(info->rest_encoding(), wire);
    EXPECT_EQ(info->mesh_id(), mesh->id());
    EXPECT_EQ(info->bytes(), mesh->byte_size());
    auto got = t.client->GetMesh(info->mesh_id());
    ASSERT_TRUE(got.ok());
    EXPECT_EQ(got->rest_encoding(), wire);
    for (const char* backend : {"simd", "simd-openmp", "serial"}) {
      for (uint64_t frame = 0; frame < 2; ++frame) {
        const auto palette = MakeSyntheticPalette(kJoints, 8, frame);
        client::FrameResult result;
        Status s = t.client->Skin(info->mesh_id(), palette, frame,
                                  {.backend = backend, .want_normals = frame == 1}, &result);
        ASSERT_TRUE(s.ok()) << backend << ": " << s.ToString();
        ExpectMatches(*mesh, palette, result.positions, result.normals,
                      std::string(backend) + " " + std::string(RestEncodingName(encoding)) +
                          " frame " + std::to_string(frame));
      }
    }
    // Streamed frames on simd-openmp.
    int seen = 0;
    client::StreamOptions options{
        .mesh_id = info->mesh_id(), .backend = "simd-openmp", .want_normals = true, .frames = 4};
    Status streamed = client::StreamFrames(
        *t.client, options, [](uint64_t f) { return MakeSyntheticPalette(kJoints, 9, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          ASSERT_TRUE(r.status.ok()) << r.status.ToString();
          ExpectMatches(*mesh, MakeSyntheticPalette(kJoints, 9, r.frame), r.positions, r.normals,
                        "streamed frame " + std::to_string(r.frame));
          ++seen;
        });
    ASSERT_TRUE(streamed.ok()) << streamed.ToString();
    EXPECT_EQ(seen, 4);
    // A server that lost the mesh gets it again in the same encoding: the same id.
    ASSERT_TRUE(t.client->DeleteMesh(info->mesh_id()).ok());
    ASSERT_TRUE(t.client->Reupload(info->mesh_id()).ok());
    got = t.client->GetMesh(info->mesh_id());
    ASSERT_TRUE(got.ok()) << got.status().ToString();
    EXPECT_EQ(got->rest_encoding(), wire);
  }
  // The raw wire's field, as other clients set it.
  auto raw = Upload(*t.client, arrays, v1::REST_ENCODING_QUANTIZED16);
  ASSERT_TRUE(raw.ok()) << raw.status().ToString();
  EXPECT_EQ(raw->mesh_id(),
            Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16}).value()->id());
}

// `opencl` (PoCL here) reads the integers on the device: unary frames of both encodings,
// with and without normals, and streamed frames, against the reference on the decoded input;
// BackendInfo says it reads the stream, and dual quaternions are refused as on `simd`.
TEST(QuantizedServiceTest, OpenClSkinsTheQuantizedStreamLikeTheDecodedReference) {
  TestServer t;
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  const auto found = std::find_if(list->backends().begin(), list->backends().end(),
                                  [](const auto& b) { return b.id() == "opencl"; });
  ASSERT_NE(found, list->backends().end());
  if (!found->available()) GTEST_SKIP() << "opencl unavailable: " << found->unavailable_reason();
  EXPECT_TRUE(found->quantized_rest());
  const MeshArrays arrays = Arrays();
  for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
    auto info = t.client->Upload(arrays, {.rest_encoding = encoding});
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    const auto mesh = Mesh::Create(arrays, {.rest_encoding = encoding}).value();
    const std::string what = "opencl " + std::string(RestEncodingName(encoding));
    for (uint64_t frame = 0; frame < 2; ++frame) {
      const auto palette = MakeSyntheticPalette(kJoints, 8, frame);
      client::FrameResult result;
      Status s = t.client->Skin(info->mesh_id(), palette, frame,
                                {.backend = "opencl", .want_normals = frame == 1}, &result);
      ASSERT_TRUE(s.ok()) << what << ": " << s.ToString();
      ExpectMatches(*mesh, palette, result.positions, result.normals,
                    what + " frame " + std::to_string(frame));
    }
    int seen = 0;
    client::StreamOptions options{
        .mesh_id = info->mesh_id(), .backend = "opencl", .want_normals = true, .frames = 3};
    Status streamed = client::StreamFrames(
        *t.client, options, [](uint64_t f) { return MakeSyntheticPalette(kJoints, 9, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          ASSERT_TRUE(r.status.ok()) << r.status.ToString();
          ExpectMatches(*mesh, MakeSyntheticPalette(kJoints, 9, r.frame), r.positions, r.normals,
                        what + " streamed frame " + std::to_string(r.frame));
          ++seen;
        });
    ASSERT_TRUE(streamed.ok()) << streamed.ToString();
    EXPECT_EQ(seen, 3);
    client::FrameResult result;
    Status s =
        t.client->Skin(info->mesh_id(), MakeRigidPalette(kJoints, 1, 1), 0,
                       {.backend = "opencl", .method = SkinningMethod::kDualQuaternion}, &result);
    EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
    EXPECT_NE(s.message().find("linear method only"), std::string::npos) << s.message();
  }
}

// A mesh with tangents uploaded quantized keeps them in the stream, and every backend that
// reads the integers skins them: `simd`, `simd-openmp` and (where available) `opencl` and
// `opencl-zerocopy`, against the float64 reference on the decoded input (tangents within
// CompareWithReference's tolerance, w exact).
TEST(QuantizedServiceTest, TangentsOfAQuantizedMeshComeFromEveryBackendThatReadsTheStream) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2003,
                                               .influences = 4,
                                               .joint_count = kJoints,
                                               .normals = true,
                                               .tangents = true,
                                               .seed = 23});
  auto info = t.client->Upload(arrays, {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays, {.rest_encoding = RestEncoding::kQuantized16}).value();
  EXPECT_EQ(info->mesh_id(), mesh->id());
  EXPECT_EQ(info->rest_encoding(), v1::REST_ENCODING_QUANTIZED16);
  const auto palette = MakeSyntheticPalette(kJoints, 8, 2);
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok()) << list.status().ToString();
  uint64_t frame = 1;
  std::string unavailable;  // OpenCL without a platform: said as a skip after the others ran
  for (const char* backend : {"simd", "simd-openmp", "opencl", "opencl-zerocopy"}) {
    const auto listed = std::find_if(list->backends().begin(), list->backends().end(),
                                     [&](const auto& b) { return b.id() == backend; });
    ASSERT_NE(listed, list->backends().end()) << backend;
    if (!listed->available()) {
      ASSERT_EQ(std::string(backend).rfind("opencl", 0), 0u)
          << backend << " unavailable: " << listed->unavailable_reason();
      unavailable += std::string(" ") + backend + " (" + listed->unavailable_reason() + ")";
      continue;
    }
    client::FrameResult result;
    Status s =
        t.client->Skin(info->mesh_id(), palette, ++frame,
                       {.backend = backend, .want_normals = true, .want_tangents = true}, &result);
    ASSERT_TRUE(s.ok()) << backend << ": " << s.ToString();
    ASSERT_EQ(result.tangents.size(), 4u * 2003) << backend;
    const Deviation d = CompareWithReference(*mesh, palette, result.positions, result.normals,
                                             SkinningMethod::kLinear, {}, result.tangents);
    EXPECT_TRUE(d.within_tolerance())
        << backend << ": tangent error " << d.max_tangent_error << " (tolerance "
        << d.tangent_tolerance << "), position error " << d.max_position_error;
  }
  if (!unavailable.empty()) GTEST_SKIP() << "unavailable:" << unavailable;
}

TEST(QuantizedServiceTest, BadRequestsAreRefusedNamingTheReason) {
  TestServer t;
  const MeshArrays arrays = Arrays();
  auto unknown = Upload(*t.client, arrays, 7);
  EXPECT_EQ(unknown.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(unknown.status().message().find("header.rest_encoding = 7 is unknown"),
            std::string::npos)
      << unknown.status().message();
  auto morph = Upload(*t.client, arrays, v1::REST_ENCODING_QUANTIZED16, {10, 20});
  EXPECT_EQ(morph.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(morph.status().message().find("quantized rest stream carries no morph targets"),
            std::string::npos)
      << morph.status().message();
  EXPECT_EQ(t.client->GetServerStats()->meshes(), 0u) << "nothing stored";

  auto info = Upload(*t.client, arrays, v1::REST_ENCODING_QUANTIZED16);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  client::FrameResult result;
  Status s =
      t.client->Skin(info->mesh_id(), MakeRigidPalette(kJoints, 1, 1), 0,
                     {.backend = "simd", .method = SkinningMethod::kDualQuaternion}, &result);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
  EXPECT_NE(s.message().find("linear method only"), std::string::npos) << s.message();
  // The float values it decodes to skin with dual quaternions elsewhere.
  s = t.client->Skin(info->mesh_id(), MakeRigidPalette(kJoints, 1, 1), 0,
                     {.backend = "serial", .method = SkinningMethod::kDualQuaternion}, &result);
  EXPECT_TRUE(s.ok()) << s.ToString();
}

}  // namespace
}  // namespace skinserve::testing
