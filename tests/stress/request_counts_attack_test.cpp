// Requests whose counts would make the server hold far more than their bytes (issue 42):
// a StreamSkin frame of 4 MB (gRPC's message limit) with instances = 2,000,000 and as many
// empty instance_morph_weights entries, 2 bytes each on the wire. Protobuf parsed each into
// ~210 MB that the stream kept while it was open, charged to no budget (measured on main
// on 2026-11-28: 4 streams took the server from 110 MB to 957 MB). Now the server counts
// the entries before it parses anything: each such frame is answered INVALID_ARGUMENT
// naming the field and its limit, the stream goes on (its next good frame is answered
// right), the server's RSS stays within kMarginMb of its resting size, and a well-behaved
// stream on another connection keeps every frame correct (float64 reference).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "own_connection.h"
#include "process_probe.h"
#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

constexpr int kAttackStreams = 4;
constexpr int kFramesEach = 6;
constexpr int kEntries = 2'000'000;
// The wire bytes of the frames gRPC holds while the server reads them (4 streams of 4 MB,
// HTTP/2 windows) and the allocator's slack; far below one parsed frame (~210 MB).
// Under AddressSanitizer freed memory waits in its quarantine first.
constexpr uint64_t kMarginMb = 96 + kSanitizerQuarantineMb;

TEST(RequestCountsAttackTest, CountsOverTheirLimitsAreRefusedBeforeTheServerHoldsThem) {
  ServerChild server({"--log-level", "warn", "--threads", "2", "--default-backend", "sse"});
  ASSERT_TRUE(server.ready()) << server.error();
  client::SkinClient setup(client::MakeChannel(server.target()));
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 5'000, .influences = 2, .joint_count = 77});
  const auto mesh = Mesh::Create(arrays).value();
  auto id = setup.Upload(arrays);
  ASSERT_TRUE(id.ok()) << id.status().ToString();

  v1::SkinRequest hostile;
  hostile.set_mesh_id(id->mesh_id());
  hostile.set_instances(kEntries);
  for (int i = 0; i < kEntries; ++i) hostile.add_instance_morph_weights();
  ASSERT_LE(hostile.ByteSizeLong(), 4u << 20) << "the attack must fit gRPC's message limit";

  std::this_thread::sleep_for(500ms);
  const uint64_t resting_mb = RssMb(server.pid());
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> peak_mb{resting_mb};
  std::thread watch([&] {
    while (!stop) {
      peak_mb = std::max(peak_mb.load(), RssMb(server.pid()));
      std::this_thread::sleep_for(20ms);
    }
  });
  // The well-behaved stream, on its own connection through the whole attack.
  std::atomic<bool> stop_good{false};
  client::StreamSummary summary;
  uint64_t wrong = 0, failed = 0;
  std::thread good([&] {
    client::SkinClient own(OwnConnection(server.target()));
    (void)client::StreamFrames(
        own,
        {.mesh_id = id->mesh_id(),
         .backend = "sse",
         .frames = 1'000'000,
         .window = 2,
         .max_reconnects = 0,
         .stop = &stop_good},
        [](uint64_t f) { return MakeSyntheticPalette(77, 3, f); },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          if (!r.status.ok()) {
            ++failed;
            ADD_FAILURE() << "good frame " << r.frame << ": " << r.status.ToString();
          } else if (!CompareWithReference(*mesh, MakeSyntheticPalette(77, 3, r.frame), r.positions,
                                           {})
                          .within_tolerance()) {
            ++wrong;
          }
        },
        &summary);
  });

  std::vector<std::thread> attackers;
  std::atomic<int> refused_named{0}, good_after_refusal{0};
  for (int s = 0; s < kAttackStreams; ++s) {
    attackers.emplace_back([&, s] {
      auto stub = v1::Skinning::NewStub(OwnConnection(server.target()));
      grpc::ClientContext context;
      auto stream = stub->StreamSkin(&context);
      v1::SkinRequest request = hostile;
      for (int f = 0; f < kFramesEach; ++f) {
        request.set_frame(static_cast<uint64_t>(s * 100 + f));
        if (!stream->Write(request)) break;
        v1::SkinResponse part;
        if (!stream->Read(&part)) break;
        EXPECT_EQ(part.frame(), request.frame());
        EXPECT_EQ(part.error().code(), grpc::StatusCode::INVALID_ARGUMENT);
        if (part.error().message().find("instance_morph_weights has more than 64 entries") !=
            std::string::npos) {
          ++refused_named;
        } else {
          ADD_FAILURE() << part.error().message();
        }
      }
      // The stream survived its refused frames: a good frame on it is answered right.
      v1::SkinRequest fine;
      fine.set_mesh_id(id->mesh_id());
      fine.set_frame(7);
      const std::vector<float> palette = MakeSyntheticPalette(77, 3, 7);
      fine.set_palette(palette.data(), palette.size() * sizeof(float));
      ASSERT_TRUE(stream->Write(fine));
      std::vector<float> positions;
      v1::SkinResponse part;
      while (stream->Read(&part)) {
        ASSERT_FALSE(part.has_error()) << part.error().message();
        const auto* values = reinterpret_cast<const float*>(part.positions().data());
        positions.insert(positions.end(), values, values + part.positions().size() / 4);
        if (part.last()) break;
      }
      if (CompareWithReference(*mesh, palette, positions, {}).within_tolerance()) {
        ++good_after_refusal;
      }
      stream->WritesDone();
      EXPECT_TRUE(stream->Finish().ok());
    });
  }
  for (auto& a : attackers) a.join();
  std::this_thread::sleep_for(300ms);
  stop_good = true;
  good.join();
  stop = true;
  watch.join();

  std::printf(
      "server RSS resting %lu MB, peak %lu MB (limit resting + %lu); good stream: %lu "
      "sent, %lu answered, %lu wrong\n",
      resting_mb, peak_mb.load(), kMarginMb, summary.sent, summary.answered, wrong);
  EXPECT_EQ(refused_named, kAttackStreams * kFramesEach);
  EXPECT_EQ(good_after_refusal, kAttackStreams);
  EXPECT_LE(peak_mb.load(), resting_mb + kMarginMb);
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(failed, 0u);
  EXPECT_GT(summary.answered, 0u);
  EXPECT_EQ(summary.sent, summary.answered + summary.failed) << "a frame was lost";
}

}  // namespace
}  // namespace skinserve::testing
