// Many streams at once and full queues, against a real server. (A cancelled stream:
// tests/server/rpc/stream_skin_reactor_test.cpp.)
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

TEST(ConcurrencyTest, SixteenStreamsOnMixedBackendsAllCorrect) {
  TestServer t;
  const std::vector<std::string> backends = {"serial",     "openmp", "sse",
                                             "sse-openmp", "opencl", "opencl-zerocopy"};
  std::vector<MeshArrays> meshes;
  std::vector<std::string> ids;
  for (uint32_t i = 0; i < 4; ++i) {
    meshes.push_back(MakeSyntheticMesh(
        {.vertex_count = 4000 + 999 * i, .influences = 1 + i, .normals = i % 2 == 1, .seed = i}));
    auto info = t.client->Upload(meshes.back());
    ASSERT_TRUE(info.ok());
    ids.push_back(info->mesh_id());
  }
  std::atomic<int> good{0}, bad{0};
  std::vector<std::thread> streams;
  for (int s = 0; s < 16; ++s) {
    streams.emplace_back([&, s] {
      const int m = s % 4;
      auto mesh = Mesh::Create(meshes[m]).value();
      client::SkinClient own(client::MakeChannel(t.target));  // a connection per stream
      Status status = client::StreamFrames(
          own,
          {.mesh_id = ids[m],
           .backend = backends[s % backends.size()],
           .want_normals = m % 2 == 1,
           .frames = 12,
           .window = 1 + s % 4},
          [&](uint64_t f) { return MakeSyntheticPalette(77, s, f); },
          [&](client::FrameResult& r, std::chrono::nanoseconds) {
            const auto palette = MakeSyntheticPalette(77, s, r.frame);
            const Deviation d = CompareWithReference(
                *mesh, palette, r.positions,
                m % 2 == 1 ? std::span<const float>(r.normals) : std::span<const float>());
            (r.status.ok() && d.within_tolerance() ? good : bad).fetch_add(1);
          });
      if (!status.ok()) bad.fetch_add(1000);
    });
  }
  for (auto& thread : streams) thread.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_EQ(good.load(), 16 * 12);
}

TEST(ConcurrencyTest, AFullQueueAnswersResourceExhaustedAndNeverHangs) {
  server::ServerOptions options;
  options.threads = 1;
  options.queue = 1;
  TestServer t(options);
  auto info = t.client->Upload(MakeSyntheticMesh({.vertex_count = 400'000, .influences = 4}));
  ASSERT_TRUE(info.ok());
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  std::atomic<int> ok{0}, exhausted{0}, other{0};
  std::vector<std::thread> callers;
  for (int i = 0; i < 12; ++i) {
    callers.emplace_back([&] {
      client::SkinClient own(client::MakeChannel(t.target));
      client::FrameResult result;
      Status s = own.Skin(info->mesh_id(), "serial", palette, 0, false, &result);
      if (s.ok()) {
        ok.fetch_add(1);
      } else if (s.code() == StatusCode::kResourceExhausted &&
                 s.message().find("queue is full") != std::string::npos) {
        exhausted.fetch_add(1);
      } else {
        other.fetch_add(1);
      }
    });
  }
  for (auto& caller : callers) caller.join();
  EXPECT_EQ(ok + exhausted, 12);
  EXPECT_EQ(other.load(), 0);
  EXPECT_GE(ok.load(), 1);
  EXPECT_EQ(t.client->GetServerStats()->rejected_queue_full(), static_cast<uint64_t>(exhausted));
}

}  // namespace
}  // namespace skinserve::testing
