// Bad input gets the right status code and a message naming the field and the limit, and
// loses nothing: no half mesh is stored. (A bad frame on a stream fails alone:
// tests/server/rpc/stream_skin_reactor_test.cpp.)
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include "expect_status.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

// Sends `messages` as one UploadMesh call; returns its status.
Status RawUpload(client::SkinClient& c, const std::vector<v1::UploadMeshRequest>& messages) {
  return RawUploadMesh(c, messages).status();
}

// Sends `messages` as they are (valid protobuf or not) on `method`, half-closes, reads
// every answer and returns the call's status.
grpc::Status RawCall(const std::string& target, const std::string& method,
                     const std::vector<std::string>& messages) {
  grpc::GenericStub stub(client::MakeChannel(target));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  grpc::CompletionQueue cq;
  void* tag = nullptr;
  bool ok = false;
  // One operation at a time, so each completion is the one just started.
  auto wait = [&] { return cq.Next(&tag, &ok) && ok; };
  auto call = stub.PrepareCall(&context, method, &cq);
  call->StartCall(nullptr);
  if (wait()) {
    for (const std::string& m : messages) {
      grpc::Slice slice(m);
      call->Write(grpc::ByteBuffer(&slice, 1), nullptr);
      if (!wait()) break;
    }
    call->WritesDone(nullptr);
    wait();
    grpc::ByteBuffer answer;
    do {
      call->Read(&answer, nullptr);
    } while (wait());
  }
  grpc::Status status;
  call->Finish(&status, nullptr);
  wait();
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
  return status;
}

v1::UploadMeshRequest Header(uint32_t v, uint32_t b, uint32_t j, bool normals = false) {
  v1::UploadMeshRequest m;
  m.mutable_header()->set_vertex_count(v);
  m.mutable_header()->set_influences(b);
  m.mutable_header()->set_joint_count(j);
  m.mutable_header()->set_has_normals(normals);
  return m;
}

v1::UploadMeshRequest Chunk(v1::MeshArray array, uint64_t offset, const void* data,
                            std::size_t bytes) {
  v1::UploadMeshRequest m;
  m.mutable_chunk()->set_array(array);
  m.mutable_chunk()->set_offset(offset);
  m.mutable_chunk()->set_data(static_cast<const char*>(data), bytes);
  return m;
}

TEST(BadInputTest, UploadsThatDisagreeWithTheirHeaderStoreNothing) {
  TestServer t;
  const MeshArrays a = MakeSyntheticMesh({.vertex_count = 100, .influences = 2});
  const auto positions = Chunk(v1::MESH_ARRAY_POSITIONS, 0, a.positions.data(), 1200);
  const auto joints = Chunk(v1::MESH_ARRAY_JOINTS, 0, a.joints.data(), 400);
  const auto weights = Chunk(v1::MESH_ARRAY_WEIGHTS, 0, a.weights.data(), 800);

  ExpectStatus(RawUpload(*t.client, {positions}), StatusCode::kInvalidArgument,
               "chunk before header");
  ExpectStatus(RawUpload(*t.client, {Header(100, 2, 77), positions, joints}),
               StatusCode::kInvalidArgument, "upload truncated: weights has 0 of 200 values");
  ExpectStatus(RawUpload(*t.client, {Header(100, 2, 77), positions, positions}),
               StatusCode::kInvalidArgument, "positions chunk at offset 0; expected offset 300");
  ExpectStatus(RawUpload(*t.client, {Header(50, 2, 77), positions}), StatusCode::kInvalidArgument,
               "positions chunk ends at value 300, past the 150 values the header implies");
  ExpectStatus(RawUpload(*t.client, {Header(100, 2, 77),
                                     Chunk(v1::MESH_ARRAY_NORMALS, 0, a.positions.data(), 12)}),
               StatusCode::kInvalidArgument, "header says has_normals = false");
  ExpectStatus(RawUpload(*t.client,
                         {Header(100, 2, 77), Chunk(v1::MESH_ARRAY_JOINTS, 0, a.joints.data(), 3)}),
               StatusCode::kInvalidArgument, "not whole 2-byte values");
  ExpectStatus(RawUpload(*t.client, {Header(100, 2, 77), Header(100, 2, 77)}),
               StatusCode::kInvalidArgument, "header sent twice");
  ExpectStatus(RawUpload(*t.client, {}), StatusCode::kInvalidArgument, "without a header");

  // A joint index past joint_count is caught by validation once the arrays are complete.
  MeshArrays bad = a;
  bad.joints[2 * 17 + 1] = 77;
  ExpectStatus(
      RawUpload(*t.client, {Header(100, 2, 77), positions,
                            Chunk(v1::MESH_ARRAY_JOINTS, 0, bad.joints.data(), 400), weights}),
      StatusCode::kInvalidArgument,
      "joints[vertex 17, influence 1] = 77 is not below joint_count 77");

  EXPECT_EQ(t.client->GetServerStats()->meshes(), 0u) << "no half mesh may be stored";
  EXPECT_TRUE(RawUpload(*t.client, {Header(100, 2, 77), positions, joints, weights}).ok());
  EXPECT_EQ(t.client->GetServerStats()->meshes(), 1u);
}

TEST(BadInputTest, SizesOverTheLimitsAreRefusedFromTheHeader) {
  server::ServerOptions options;
  options.max_vertices = 1000;
  options.max_joints = 64;
  options.mesh_budget_mb = 1;
  TestServer t(options);
  ExpectStatus(RawUpload(*t.client, {Header(1001, 2, 10)}), StatusCode::kResourceExhausted,
               "vertex_count 1001 exceeds the limit of 1000 vertices");
  ExpectStatus(RawUpload(*t.client, {Header(10, 2, 65)}), StatusCode::kResourceExhausted,
               "joint_count 65 exceeds the limit of 64 joints");
  ExpectStatus(RawUpload(*t.client, {Header(10, 9, 10)}), StatusCode::kInvalidArgument,
               "influences is 9; it must be 1..8");
  ExpectStatus(RawUpload(*t.client, {Header(0, 2, 10)}), StatusCode::kInvalidArgument,
               "vertex_count is 0");
  // 4e9 vertices would be 100+ GB: refused before any allocation.
  ExpectStatus(RawUpload(*t.client, {Header(4'000'000'000u, 8, 10)}),
               StatusCode::kResourceExhausted, "exceeds the limit");
}

TEST(BadInputTest, BytesThatAreNoSkinRequestAreRefusedNamingTheMessage) {
  TestServer t;
  auto info = t.client->Upload(MakeSyntheticMesh({.vertex_count = 200, .influences = 2}));
  ASSERT_TRUE(info.ok());
  v1::SkinRequest good;
  good.set_mesh_id(info->mesh_id());
  good.set_backend("serial");
  good.set_palette(wire::EncodeFloats(MakeSyntheticPalette(77, 1, 0)));
  const std::string truncated("\x08", 1);  // field 1's varint, cut off
  // The raw methods parse requests themselves: a message that is no SkinRequest ends the
  // call with INVALID_ARGUMENT naming it (nothing else names its frame), after the valid
  // messages before it were answered.
  const grpc::Status stream =
      RawCall(t.target, "/skinserve.v1.Skinning/StreamSkin", {good.SerializeAsString(), truncated});
  EXPECT_EQ(stream.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << stream.error_message();
  EXPECT_NE(stream.error_message().find("message 2 on this stream is not a valid "
                                        "skinserve.v1.SkinRequest"),
            std::string::npos)
      << stream.error_message();
  const grpc::Status skin = RawCall(t.target, "/skinserve.v1.Skinning/Skin", {truncated});
  EXPECT_EQ(skin.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << skin.error_message();
  EXPECT_NE(skin.error_message().find("not a valid skinserve.v1.SkinRequest"), std::string::npos)
      << skin.error_message();
  // Valid bytes through the same path are answered, and the server serves on.
  EXPECT_TRUE(RawCall(t.target, "/skinserve.v1.Skinning/Skin", {good.SerializeAsString()}).ok());
  client::FrameResult result;
  EXPECT_TRUE(
      t.client->Skin(info->mesh_id(), "serial", MakeSyntheticPalette(77, 1, 0), 0, false, &result)
          .ok());
}

TEST(BadInputTest, BadFramesGetTheirErrorNamingTheField) {
  TestServer t;
  auto info = t.client->Upload(MakeSyntheticMesh({.vertex_count = 200, .influences = 2}));
  ASSERT_TRUE(info.ok());
  const auto good = MakeSyntheticPalette(77, 1, 0);
  client::FrameResult result;

  ExpectStatus(t.client->Skin("0000", "serial", good, 0, false, &result), StatusCode::kNotFound,
               "upload it again");
  ExpectStatus(t.client->Skin(info->mesh_id(), "warp", good, 0, false, &result),
               StatusCode::kInvalidArgument,
               "available backends: serial, openmp, sse, sse-openmp, simd, simd-openmp, opencl, "
               "opencl-zerocopy, passthrough");
  std::vector<float> short_palette(good.begin(), good.end() - 12);
  ExpectStatus(t.client->Skin(info->mesh_id(), "serial", short_palette, 0, false, &result),
               StatusCode::kInvalidArgument, "expected 12 * joint_count = 924");
  std::vector<float> nan_palette = good;
  nan_palette[12 * 5 + 3] = std::nanf("");
  ExpectStatus(t.client->Skin(info->mesh_id(), "serial", nan_palette, 0, false, &result),
               StatusCode::kInvalidArgument, "palette[joint 5][row 0, col 3]");
  ExpectStatus(t.client->Skin(info->mesh_id(), "serial", good, 0, true, &result),
               StatusCode::kInvalidArgument, "has no normals");
  // On a stream, each bad frame fails alone: tests/server/rpc/stream_skin_reactor_test.cpp.
}

}  // namespace
}  // namespace skinserve::testing
