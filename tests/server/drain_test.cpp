// Shutdown with a stream open: the stream stops being read, every frame the server read
// is answered (and matches the reference), and the stream ends UNAVAILABLE, so its client
// can go on at another replica. Without draining it would be cancelled at the deadline.
// The same over TCP and over a Unix socket (whose connections the server accepts itself).
#include <gtest/gtest.h>

#include <thread>

#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

void ShutdownAnswersEveryFrameReadThenEndsStreamsUnavailable(Transport transport) {
  TestServer t({}, transport);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 20'000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays).value();

  grpc::ClientContext context;
  auto stream = t.client->stub().StreamSkin(&context);
  auto send = [&](uint64_t frame) {
    v1::SkinRequest request;
    request.set_mesh_id(info->mesh_id());
    request.set_backend("serial");
    request.set_frame(frame);
    request.set_palette(wire::EncodeFloats(MakeSyntheticPalette(77, 3, frame)));
    return stream->Write(request);
  };
  // Reads one whole frame; false when the stream has ended instead.
  auto receive = [&](client::FrameResult* result) {
    *result = client::FrameResult();
    client::FrameAssembler assembler;
    v1::SkinResponse part;
    while (stream->Read(&part)) {
      if (assembler.Add(part, result)) return true;
    }
    return false;
  };
  auto expect_matches = [&](const client::FrameResult& r) {
    ASSERT_TRUE(r.status.ok()) << r.status.ToString();
    const auto palette = MakeSyntheticPalette(77, 3, r.frame);
    EXPECT_TRUE(CompareWithReference(*mesh, palette, r.positions, {}).within_tolerance())
        << "frame " << r.frame;
  };

  ASSERT_TRUE(send(0));
  client::FrameResult result;
  ASSERT_TRUE(receive(&result));  // the stream is live
  EXPECT_EQ(result.frame, 0u);
  expect_matches(result);
  for (uint64_t frame = 1; frame <= 4; ++frame) ASSERT_TRUE(send(frame));

  // A long grace: the server must not need it, the stream ends once its frames are answered.
  std::thread shutdown([&] { t.server->Shutdown(std::chrono::seconds(60)); });
  uint64_t expected = 1;
  while (receive(&result)) {
    EXPECT_EQ(result.frame, expected++) << "answers keep request order";
    expect_matches(result);
  }
  const grpc::Status status = stream->Finish();
  shutdown.join();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
  EXPECT_NE(status.error_message().find("shutting down"), std::string::npos)
      << status.error_message();
  // Frames the server read were answered; the rest (if any) were never read, and the
  // message says so. Either way none came back twice or out of order (checked above).
  EXPECT_LE(expected, 5u);
}

TEST(DrainTest, ShutdownAnswersEveryFrameReadThenEndsStreamsUnavailable) {
  ShutdownAnswersEveryFrameReadThenEndsStreamsUnavailable(Transport::kTcp);
}

TEST(DrainTest, OnAUnixSocketShutdownAnswersEveryFrameReadThenEndsStreamsUnavailable) {
  ShutdownAnswersEveryFrameReadThenEndsStreamsUnavailable(Transport::kUnixSocket);
}

}  // namespace
}  // namespace skinserve::testing
