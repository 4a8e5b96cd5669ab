// StreamSkinReactor's own behaviour, over a real server on loopback and the raw stub (no
// client library windowing or reordering in between): answers go out in request order
// even when later frames finish first; at most --stream-window frames are in flight (the
// reactor stops reading, it does not refuse), and a frame the engine's full queue refuses
// is answered RESOURCE_EXHAUSTED by itself while the stream goes on; a bad frame fails
// only itself, and every good frame around it matches the float64 reference; the stream
// ends OK once every frame read is answered, and a cancelled one lets go of everything.
// Every call has a deadline, so that a hang fails the test instead of stalling it.
#include "rpc/stream_skin_reactor.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <thread>

#include "expect_status.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using Stream = grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>;

constexpr uint32_t kJoints = 77;  // MakeSyntheticMesh's

// A mesh uploaded, and the same mesh on this side for the reference.
struct UploadedMesh {
  std::string id;
  std::shared_ptr<const Mesh> mesh;
};

UploadedMesh Upload(TestServer& t, uint32_t vertices, uint32_t influences) {
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = vertices, .influences = influences, .seed = vertices});
  auto info = t.client->Upload(arrays);
  EXPECT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return {info.ok() ? info->mesh_id() : "", mesh.ok() ? *mesh : nullptr};
}

v1::SkinRequest Frame(const std::string& mesh_id, uint64_t frame, const std::vector<float>& palette,
                      const std::string& backend = "serial") {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  request.set_backend(backend);
  request.set_frame(frame);
  request.set_palette(wire::EncodeFloats(palette));
  return request;
}

std::vector<float> Pose(uint64_t frame) { return MakeSyntheticPalette(kJoints, 5, frame); }

std::unique_ptr<grpc::ClientContext> WithDeadline(int seconds = 120) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(seconds));
  return context;
}

// The next frame's answer, all its parts; false when the stream ended instead.
bool ReadAnswer(Stream& stream, client::FrameResult* result) {
  client::FrameAssembler assembler;
  v1::SkinResponse part;
  while (stream.Read(&part)) {
    if (assembler.Add(part, result)) return true;
  }
  return false;
}

// The answer is frame `frame`, OK, and within float32 rounding of the float64 reference.
void ExpectReference(const client::FrameResult& result, uint64_t frame, const Mesh& mesh) {
  EXPECT_EQ(result.frame, frame);
  ASSERT_TRUE(result.status.ok()) << "frame " << frame << ": " << result.status.ToString();
  const Deviation d = CompareWithReference(mesh, Pose(frame), result.positions, {});
  EXPECT_TRUE(d.within_tolerance()) << "frame " << frame << ": position error "
                                    << d.max_position_error << " > " << d.position_tolerance;
}

TEST(StreamSkinReactorTest, AnswersKeepRequestOrderWhenLaterFramesFinishFirst) {
  server::ServerOptions options;
  options.threads = 2;         // a big frame on one thread, small ones skinned beside it
  options.stream_window = 16;  // more than the frames: the half-close is read at once
  TestServer t(options);
  const UploadedMesh big = Upload(t, 300'000, 4), small = Upload(t, 500, 1);
  auto context = WithDeadline();
  auto stream = t.client->stub().StreamSkin(context.get());
  // Even frames take milliseconds, odd ones microseconds: each small frame is done before
  // the big one before it, and still waits for it.
  for (uint64_t f = 0; f < 8; ++f) {
    ASSERT_TRUE(stream->Write(Frame(f % 2 == 0 ? big.id : small.id, f, Pose(f))));
  }
  ASSERT_TRUE(stream->WritesDone());  // the end comes while all eight are in flight
  client::FrameResult result;
  for (uint64_t f = 0; f < 8; ++f) {
    ASSERT_TRUE(ReadAnswer(*stream, &result)) << "the stream ended before frame " << f;
    ExpectReference(result, f, f % 2 == 0 ? *big.mesh : *small.mesh);
  }
  EXPECT_FALSE(ReadAnswer(*stream, &result)) << "an answer nobody asked for";
  const grpc::Status end = stream->Finish();
  EXPECT_TRUE(end.ok()) << end.error_message();
}

struct Burst {
  int answered = 0, refused = 0, other = 0;
};

// 16 frames of a 400k-vertex mesh written at once onto one stream of a server with one
// compute thread and a queue of one, then read: every frame's answer, in order, is either
// the reference or RESOURCE_EXHAUSTED for the full queue. Then one more frame, answered.
Burst SendBurst(int window) {
  server::ServerOptions options;
  options.threads = 1;
  options.queue = 1;
  options.stream_window = window;
  options.inflight_budget_mb = 1024;  // the queue, not the budget, is what refuses here
  TestServer t(options);
  const UploadedMesh mesh = Upload(t, 400'000, 4);
  auto context = WithDeadline();
  auto stream = t.client->stub().StreamSkin(context.get());
  Burst burst;
  for (uint64_t f = 0; f < 16; ++f) EXPECT_TRUE(stream->Write(Frame(mesh.id, f, Pose(f))));
  client::FrameResult result;
  for (uint64_t f = 0; f <= 16; ++f) {
    if (f == 16) {  // one more after the burst
      EXPECT_TRUE(stream->Write(Frame(mesh.id, f, Pose(f))));
    }
    if (!ReadAnswer(*stream, &result)) {
      ADD_FAILURE() << "the stream ended before frame " << f;
      break;
    }
    if (result.status.code() == StatusCode::kResourceExhausted) {
      EXPECT_EQ(result.frame, f);
      ExpectStatus(result.status, StatusCode::kResourceExhausted, "queue is full");
      ++burst.refused;
      EXPECT_LT(f, 16u) << "the frame after the burst found the queue full";
    } else {
      ExpectReference(result, f, *mesh.mesh);
      ++(result.status.ok() ? burst.answered : burst.other);
    }
  }
  EXPECT_TRUE(stream->WritesDone());
  const grpc::Status end = stream->Finish();
  EXPECT_TRUE(end.ok()) << end.error_message();
  EXPECT_EQ(t.client->GetServerStats()->rejected_queue_full(),
            static_cast<uint64_t>(burst.refused));
  return burst;
}

TEST(StreamSkinReactorTest, AtMostTheWindowIsInFlightSoAWindowOfOneNeverFillsTheQueue) {
  // One frame in flight at a time: the next is read only once the last is answered, so a
  // queue of one is never full, however fast the frames come.
  const Burst burst = SendBurst(1);
  EXPECT_EQ(burst.answered, 17);
  EXPECT_EQ(burst.refused, 0) << "more than one frame of the stream was in flight";
  EXPECT_EQ(burst.other, 0);
}

TEST(StreamSkinReactorTest, AFrameTheFullQueueRefusesIsAnsweredAloneAndTheStreamGoesOn) {
  // Sixteen in flight: the frames read while the one thread skins (milliseconds a frame)
  // and the queue holds one are refused (reading sixteen takes microseconds), each by
  // itself, in its place, without holding up the stream.
  const Burst burst = SendBurst(16);
  EXPECT_GE(burst.refused, 1) << "the queue never filled: this test checks nothing";
  EXPECT_GE(burst.answered, 3);  // the first, the one queued, the one after the burst
  EXPECT_EQ(burst.answered + burst.refused, 17);
  EXPECT_EQ(burst.other, 0);
}

TEST(StreamSkinReactorTest, ABadFrameFailsOnlyItselfAndTheFramesAroundItMatchTheReference) {
  TestServer t;
  const UploadedMesh mesh = Upload(t, 2000, 2);
  // Each bad frame is refused at another step: the reader's limits (before the parse), the
  // job's preparation (mesh, backend, palette) and the engine's checks.
  std::vector<v1::SkinRequest> frames;
  const auto good = [&](uint64_t f) { return Frame(mesh.id, f, Pose(f), "sse"); };
  std::vector<float> nan_palette = Pose(1);
  nan_palette[12 * 5 + 3] = std::nanf("");
  frames.push_back(good(0));
  frames.push_back(Frame(mesh.id, 1, nan_palette, "sse"));
  frames.push_back(good(2));
  frames.push_back(Frame(mesh.id, 3, Pose(3), "warp"));
  frames.push_back(Frame("0000", 4, Pose(4), "sse"));
  std::vector<float> short_palette = Pose(5);
  short_palette.resize(short_palette.size() - 12);  // one joint short
  frames.push_back(Frame(mesh.id, 5, short_palette));
  frames.push_back(good(6));
  v1::SkinRequest over = good(7);
  for (uint32_t i = 0; i <= kMaxMorphTargets; ++i) over.add_morph_targets(i);
  frames.push_back(over);
  frames.push_back(good(8));
  frames.push_back(good(9));

  auto context = WithDeadline();
  auto stream = t.client->stub().StreamSkin(context.get());
  for (const v1::SkinRequest& frame : frames) ASSERT_TRUE(stream->Write(frame));
  ASSERT_TRUE(stream->WritesDone());
  client::FrameResult result;
  const std::map<uint64_t, std::pair<StatusCode, std::string>> refusals = {
      {1, {StatusCode::kInvalidArgument, "palette[joint 5][row 0, col 3] = nan is not finite"}},
      {3, {StatusCode::kInvalidArgument, "available backends: serial"}},
      {4, {StatusCode::kNotFound, "upload it again"}},
      {5, {StatusCode::kInvalidArgument, "expected 12 * joint_count = 924"}},
      {7, {StatusCode::kInvalidArgument, "morph_targets has 1025 entries; at most 1024"}},
  };
  for (uint64_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(ReadAnswer(*stream, &result)) << "the stream ended before frame " << f;
    EXPECT_EQ(result.frame, f);
    if (auto it = refusals.find(f); it != refusals.end()) {
      ExpectStatus(result.status, it->second.first, it->second.second);
      EXPECT_TRUE(result.positions.empty()) << "frame " << f << " failed with vertices";
    } else {
      ExpectReference(result, f, *mesh.mesh);
    }
  }
  const grpc::Status end = stream->Finish();
  EXPECT_TRUE(end.ok()) << end.error_message();
}

TEST(StreamSkinReactorTest, AStreamWithNoFrameEndsOkWhenTheClientHalfCloses) {
  TestServer t;
  auto context = WithDeadline(30);
  auto stream = t.client->stub().StreamSkin(context.get());
  ASSERT_TRUE(stream->WritesDone());
  v1::SkinResponse part;
  EXPECT_FALSE(stream->Read(&part));
  const grpc::Status end = stream->Finish();
  EXPECT_TRUE(end.ok()) << end.error_message();
}

TEST(StreamSkinReactorTest, ACancelledStreamFreesItsResources) {
  TestServer t;
  const UploadedMesh mesh = Upload(t, 200'000, 2);
  {
    auto context = WithDeadline();
    auto stream = t.client->stub().StreamSkin(context.get());
    for (uint64_t f = 0; f < 8; ++f) ASSERT_TRUE(stream->Write(Frame(mesh.id, f, Pose(0))));
    v1::SkinResponse part;
    ASSERT_TRUE(stream->Read(&part));  // the stream is live and working
    EXPECT_EQ(t.client->GetServerStats()->open_streams(), 1u);
    context->TryCancel();
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  // The server lets go of the stream (its queued frames finish and are dropped) and of
  // the buffers its frames held.
  for (int i = 0; i < 100 && (t.client->GetServerStats()->open_streams() != 0 ||
                              t.client->GetServerStats()->inflight_bytes() != 0);
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(t.client->GetServerStats()->open_streams(), 0u);
  EXPECT_EQ(t.client->GetServerStats()->inflight_bytes(), 0u);
  // And keeps serving.
  client::FrameResult result;
  ASSERT_TRUE(t.client->Skin(mesh.id, "sse", Pose(3), 3, false, &result).ok());
  ExpectReference(result, 3, *mesh.mesh);
}

}  // namespace
}  // namespace skinserve::testing
