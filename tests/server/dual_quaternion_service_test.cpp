// Dual-quaternion skinning through a real server over loopback gRPC: ListBackends says
// which backends have which methods (every computing backend has both), a frame of every
// such backend comes back matching the float64 reference in every vertex encoding
// (float32, float16, snorm16: within the float32 tolerance plus the encoding's stated
// bound) on the unary and the streaming call, and the refusals (a backend without the method,
// a joint that is not rigid, an unknown method number) are INVALID_ARGUMENT with the
// names in the message, without ending the stream.
#include <gtest/gtest.h>

#include <algorithm>

#include "expect_status.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

bool Lists(const v1::BackendInfo& b, v1::SkinningMethod method) {
  return std::find(b.methods().begin(), b.methods().end(), method) != b.methods().end();
}

// The available backends that list dual quaternions, in the server's order.
std::vector<std::string> DualQuaternionBackends(client::SkinClient& client) {
  std::vector<std::string> ids;
  auto list = client.ListBackends();
  EXPECT_TRUE(list.ok()) << list.status().ToString();
  if (!list.ok()) return ids;
  for (const auto& b : list->backends()) {
    if (b.available() && Lists(b, v1::SKINNING_METHOD_DUAL_QUATERNION)) ids.push_back(b.id());
  }
  return ids;
}

TEST(DualQuaternionServiceTest, ListBackendsSaysWhichBackendsHaveWhichMethods) {
  TestServer t;
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok()) << list.status().ToString();
  int listing = 0;
  for (const auto& b : list->backends()) {
    EXPECT_TRUE(Lists(b, v1::SKINNING_METHOD_LINEAR)) << b.id();
    if (!b.available()) continue;  // (the SSE ones off x86, OpenCL without a platform)
    EXPECT_EQ(Lists(b, v1::SKINNING_METHOD_DUAL_QUATERNION), b.id() != "passthrough") << b.id();
    listing += Lists(b, v1::SKINNING_METHOD_DUAL_QUATERNION) ? 1 : 0;
  }
  EXPECT_GE(listing, 4) << "serial, openmp, simd and simd-openmp run everywhere";
}

TEST(DualQuaternionServiceTest, FramesMatchTheReferenceUnaryAndStreamed) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 2001, .influences = 4, .joint_count = 77, .normals = true, .seed = 8});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto mesh = Mesh::Create(arrays).value();
  const std::vector<std::string> backends = DualQuaternionBackends(*t.client);
  EXPECT_GE(backends.size(), 4u);
  const auto palette = MakeRigidPalette(77, 8, 3);
  for (const std::string& backend : backends) {
    for (VertexEncoding encoding :
         {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
      client::FrameResult result;
      ASSERT_TRUE(t.client
                      ->Skin(info->mesh_id(), palette, 3,
                             {.backend = backend,
                              .want_normals = true,
                              .method = SkinningMethod::kDualQuaternion,
                              .encoding = encoding},
                             &result)
                      .ok())
          << backend;
      ASSERT_EQ(result.bounds.size(), 1u) << backend;
      const EncodedDeviation d =
          CompareEncodedWithReference(*mesh, palette, encoding, result.bounds[0], result.positions,
                                      result.normals, SkinningMethod::kDualQuaternion);
      EXPECT_TRUE(d.within_tolerance())
          << backend << " " << VertexEncodingName(encoding) << ": position ratio "
          << d.worst_position_ratio << ", normal ratio " << d.worst_normal_ratio;
      if (encoding != VertexEncoding::kFloat32) continue;
      // And it is not the linear answer: the two methods differ on this palette.
      const Deviation linear =
          CompareWithReference(*mesh, palette, result.positions, result.normals);
      EXPECT_FALSE(linear.within_tolerance()) << backend;
    }
  }
  client::StreamOptions options{.mesh_id = info->mesh_id(),
                                .backend = "simd-openmp",
                                .want_normals = true,
                                .method = SkinningMethod::kDualQuaternion,
                                .frames = 6};
  uint64_t checked = 0;
  Status streamed = client::StreamFrames(
      *t.client, options, [](uint64_t f) { return MakeRigidPalette(77, 8, f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        const Deviation d =
            CompareWithReference(*mesh, MakeRigidPalette(77, 8, r.frame), r.positions, r.normals,
                                 SkinningMethod::kDualQuaternion);
        EXPECT_TRUE(d.within_tolerance()) << "frame " << r.frame;
        ++checked;
      });
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(checked, 6u);
}

TEST(DualQuaternionServiceTest, RefusalsNameTheBackendTheMethodAndTheJoint) {
  TestServer t;
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 100, .influences = 2, .joint_count = 6, .seed = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  client::FrameResult result;
  ExpectStatus(
      t.client->Skin(info->mesh_id(), "passthrough", MakeRigidPalette(6, 2, 0), 0, false, &result,
                     SkinningMethod::kDualQuaternion),
      StatusCode::kInvalidArgument,
      "backend 'passthrough' does not implement method dual-quaternion (it implements "
      "linear); backends here that do: " +
          [&] {
            std::string names;
            for (const std::string& id : DualQuaternionBackends(*t.client)) {
              names += (names.empty() ? "" : ", ") + id;
            }
            return names;
          }());
  std::vector<float> scaled = MakeRigidPalette(6, 2, 0);
  for (int e : {0, 1, 2, 4, 5, 6, 8, 9, 10}) scaled[kFloatsPerJoint * 4 + e] *= 1.2f;
  ExpectStatus(t.client->Skin(info->mesh_id(), "serial", scaled, 0, false, &result,
                              SkinningMethod::kDualQuaternion),
               StatusCode::kInvalidArgument, "palette[joint 4] is not rigid");
  // The same palette is fine for linear skinning.
  EXPECT_TRUE(t.client->Skin(info->mesh_id(), "serial", scaled, 0, false, &result).ok());

  // On a stream, a refused frame is answered with its error and the next one goes through.
  grpc::ClientContext context;
  auto stream = t.client->stub().StreamSkin(&context);
  auto send = [&](uint64_t frame, v1::SkinningMethod method, const std::string& backend) {
    v1::SkinRequest request;
    request.set_mesh_id(info->mesh_id());
    request.set_backend(backend);
    request.set_frame(frame);
    request.set_palette(wire::EncodeFloats(MakeRigidPalette(6, 2, frame)));
    request.set_method(method);
    EXPECT_TRUE(stream->Write(request));
    client::FrameResult r;
    client::FrameAssembler assembler;
    v1::SkinResponse part;
    while (stream->Read(&part)) {
      if (assembler.Add(part, &r)) break;
    }
    return r.status;
  };
  ExpectStatus(send(1, v1::SKINNING_METHOD_DUAL_QUATERNION, "passthrough"),
               StatusCode::kInvalidArgument, "does not implement method dual-quaternion");
  ExpectStatus(send(2, static_cast<v1::SkinningMethod>(7), "serial"), StatusCode::kInvalidArgument,
               "method = 7 is unknown");
  EXPECT_TRUE(send(3, v1::SKINNING_METHOD_DUAL_QUATERNION, "simd").ok());
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

}  // namespace
}  // namespace skinserve::testing
