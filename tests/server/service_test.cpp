// Every RPC of skinserve.v1.Skinning against a real server over loopback, with results
// checked against the float64 reference.
#include <gtest/gtest.h>

#include "skinserve/client/frame_stream.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

void ExpectMatchesReference(const MeshArrays& arrays, std::span<const float> palette,
                            const client::FrameResult& result, bool normals) {
  ASSERT_TRUE(result.status.ok()) << result.status.ToString();
  auto mesh = Mesh::Create(arrays).value();
  const Deviation d = CompareWithReference(
      *mesh, palette, result.positions,
      normals ? std::span<const float>(result.normals) : std::span<const float>());
  EXPECT_TRUE(d.within_tolerance())
      << "frame " << result.frame << ": position error " << d.max_position_error
      << ", normal error " << d.max_normal_error;
}

TEST(ServiceTest, HealthBackendsUploadGetDeleteStats) {
  TestServer t;
  EXPECT_TRUE(client::CheckHealth(t.client->channel(), std::chrono::seconds(5)).ok());
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  EXPECT_EQ(backends->backends_size(), 9);
  EXPECT_EQ(backends->default_backend(), "sse-openmp");
  for (const auto& info : backends->backends()) {  // the run-time SIMD target travels
    if (info.id() == "simd" || info.id() == "simd-openmp") {
      EXPECT_EQ(info.simd_target(), RunnableSimdTargets().front()) << info.id();
    } else {
      EXPECT_EQ(info.simd_target(), "") << info.id();
    }
  }

  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 1234, .influences = 3});
  auto first = t.client->Upload(arrays);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  EXPECT_EQ(first->vertex_count(), 1234u);
  EXPECT_FALSE(first->already_stored());
  auto again = t.client->Upload(arrays);  // same content: same id, stored once
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->mesh_id(), first->mesh_id());
  EXPECT_TRUE(again->already_stored());
  EXPECT_EQ(t.client->GetServerStats()->meshes(), 1u);

  auto got = t.client->GetMesh(first->mesh_id());
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->influences(), 3u);
  EXPECT_EQ(*t.client->DeleteMesh(first->mesh_id()), true);
  EXPECT_EQ(*t.client->DeleteMesh(first->mesh_id()), false);
  EXPECT_EQ(t.client->GetMesh(first->mesh_id()).status().code(), StatusCode::kNotFound);
}

// BackendInfo.encoded_outputs on the wire: the OpenCL backends (PoCL here) write float16 and
// snorm16 themselves, on the device; every CPU backend writes none (the server encodes).
TEST(ServiceTest, BackendsListTheEncodingsTheyWriteThemselves) {
  TestServer t;
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok()) << list.status().ToString();
  int opencl = 0, simd = 0;
  for (const auto& b : list->backends()) {
    SCOPED_TRACE(b.id());
    std::vector<int> listed(b.encoded_outputs().begin(), b.encoded_outputs().end());
    if (b.id() == "opencl" || b.id() == "opencl-zerocopy") {
      ASSERT_TRUE(b.available()) << b.id() << " (PoCL) must be available for this test: "
                                 << b.unavailable_reason();
      EXPECT_EQ(listed, (std::vector<int>{v1::ENCODING_FLOAT16, v1::ENCODING_SNORM16}));
      ++opencl;
    } else if (b.id() == "simd" || b.id() == "simd-openmp") {  // the loop encodes itself
      EXPECT_EQ(listed, (std::vector<int>{v1::ENCODING_FLOAT16, v1::ENCODING_SNORM16}));
      ++simd;
    } else {
      EXPECT_TRUE(listed.empty()) << listed.size() << " encodings listed";
    }
  }
  EXPECT_EQ(opencl, 2);
  EXPECT_EQ(simd, 2);
}

// Without --opencl-device-timing the OpenCL queues are not profiled: the frame is right and
// its device times are 0.
TEST(ServiceTest, OpenClDeviceTimesOnlyWhenAskedFor) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2000, .influences = 2, .seed = 4});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int checked = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id().rfind("opencl", 0) != 0) continue;
    SCOPED_TRACE(backend.id());
    const auto palette = MakeSyntheticPalette(77, 5, 0);
    client::FrameResult result;
    ASSERT_TRUE(t.client->Skin(info->mesh_id(), backend.id(), palette, 0, false, &result).ok());
    ExpectMatchesReference(arrays, palette, result, false);
    EXPECT_EQ(result.timing.device_kernel_ns(), 0);
    EXPECT_EQ(result.timing.device_transfer_ns(), 0);
    ++checked;
  }
  if (checked == 0) GTEST_SKIP() << "no OpenCL backend is available here";
}

TEST(ServiceTest, EveryBackendThroughSkinAndStreamSkin) {
  server::ServerOptions options;
  options.opencl_device_timing = true;  // the device times below
  TestServer t(options);
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 3001, .influences = 4, .normals = true, .seed = 9});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    SCOPED_TRACE(backend.id());
    const auto palette = MakeSyntheticPalette(77, 3, 0);
    client::FrameResult result;
    ASSERT_TRUE(t.client->Skin(info->mesh_id(), backend.id(), palette, 0, true, &result).ok());
    ExpectMatchesReference(arrays, palette, result, true);
    // The device's share of the frame: from OpenCL's profiling events (--opencl-device-timing),
    // zero elsewhere.
    if (backend.id().rfind("opencl", 0) == 0) {
      EXPECT_GT(result.timing.device_kernel_ns(), 0);
      EXPECT_GT(result.timing.device_transfer_ns(), 0);
    } else {
      EXPECT_EQ(result.timing.device_kernel_ns(), 0);
      EXPECT_EQ(result.timing.device_transfer_ns(), 0);
    }

    int frames = 0;
    Status s = client::StreamFrames(
        *t.client, {.mesh_id = info->mesh_id(), .backend = backend.id(), .frames = 6},
        [](uint64_t f) { return MakeSyntheticPalette(77, 3, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          EXPECT_EQ(r.frame, static_cast<uint64_t>(frames)) << "answers keep request order";
          ExpectMatchesReference(arrays, MakeSyntheticPalette(77, 3, r.frame), r, false);
          ++frames;
        });
    EXPECT_TRUE(s.ok()) << s.ToString();
    EXPECT_EQ(frames, 6);
  }
  const auto stats = t.client->GetServerStats();
  ASSERT_TRUE(stats.ok());
  for (const auto& b : stats->backends()) {
    if (b.id() != "passthrough") {
      EXPECT_EQ(b.frames(), 7u) << b.id();
    }
  }
}

TEST(ServiceTest, LargeMeshThroughDefaultMessageLimits) {
  TestServer t;
  // 1.6M vertices x 4 bones: ~58 MB up, 19 MB (38 MB with normals) back per frame.
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 1'600'000, .influences = 4, .normals = true, .seed = 5});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const auto palette = MakeSyntheticPalette(77, 1, 4);
  client::FrameResult result;
  Status s = t.client->Skin(info->mesh_id(), "sse-openmp", palette, 4, true, &result);
  ASSERT_TRUE(s.ok()) << s.ToString();
  ExpectMatchesReference(arrays, palette, result, true);

  int frames = 0;
  s = client::StreamFrames(
      *t.client, {.mesh_id = info->mesh_id(), .backend = "opencl-zerocopy", .frames = 2},
      [&](uint64_t) { return palette; },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ExpectMatchesReference(arrays, palette, r, false);
        ++frames;
      });
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(frames, 2);
}

TEST(ServiceTest, ReuploadsTransparentlyWhenTheServerForgotTheMesh) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 500, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  // As if the server restarted: the mesh is gone.
  ASSERT_TRUE(t.server->engine().DeleteMesh(info->mesh_id()));
  const auto palette = MakeSyntheticPalette(77, 2, 0);
  client::FrameResult result;
  ASSERT_TRUE(t.client->Skin(info->mesh_id(), "serial", palette, 0, false, &result).ok());
  ExpectMatchesReference(arrays, palette, result, false);

  ASSERT_TRUE(t.server->engine().DeleteMesh(info->mesh_id()));
  client::StreamSummary summary;
  int frames = 0;
  Status s = client::StreamFrames(
      *t.client, {.mesh_id = info->mesh_id(), .backend = "sse", .frames = 5},
      [](uint64_t f) { return MakeSyntheticPalette(77, 2, f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ExpectMatchesReference(arrays, MakeSyntheticPalette(77, 2, r.frame), r, false);
        ++frames;
      },
      &summary);
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(frames, 5);
  EXPECT_GE(summary.reuploads, 1u);
}

// A re-upload the server refuses (here every upload: --max-uploads 0) does not vanish: the
// frame's NOT_FOUND says why the mesh could not go again, unary and streamed.
TEST(ServiceTest, AFailedReuploadSaysWhyInTheFramesError) {
  server::ServerOptions options;
  options.max_uploads = 0;
  TestServer t(options);
  auto arrays =
      std::make_shared<const MeshArrays>(MakeSyntheticMesh({.vertex_count = 100, .influences = 2}));
  const std::string mesh_id = Mesh::Create(*arrays).value()->id();
  t.client->Remember(mesh_id, arrays);
  const auto palette = MakeSyntheticPalette(77, 2, 0);
  client::FrameResult result;
  const Status s = t.client->Skin(mesh_id, "serial", palette, 0, false, &result);
  EXPECT_EQ(s.code(), StatusCode::kNotFound) << s.ToString();
  EXPECT_NE(s.message().find("re-uploading it failed: RESOURCE_EXHAUSTED"), std::string::npos)
      << s.message();
  EXPECT_NE(s.message().find("--max-uploads 0"), std::string::npos) << s.message();

  client::StreamSummary summary;
  int failed = 0;
  const Status streamed = client::StreamFrames(
      *t.client, {.mesh_id = mesh_id, .backend = "serial", .frames = 3},
      [](uint64_t f) { return MakeSyntheticPalette(77, 2, f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        EXPECT_EQ(r.status.code(), StatusCode::kNotFound);
        EXPECT_NE(r.status.message().find("re-uploading it failed: RESOURCE_EXHAUSTED"),
                  std::string::npos)
            << r.status.message();
        ++failed;
      },
      &summary);
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(failed, 3);
  EXPECT_EQ(summary.failed, 3u);
  EXPECT_EQ(summary.reuploads, 0u);
}

}  // namespace
}  // namespace skinserve::testing
