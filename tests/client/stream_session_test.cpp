// The stream session (client/src/stream_session.h) through StreamFrames and StreamTicks,
// against an in-process fake of the Skinning service whose streams break and whose mesh
// goes missing on cue. Each case runs for frames and for ticks, the session's two paths:
// a stream broken before its first answer sends its units again on the next one; one
// broken after answering fails its units in flight (each unit reaches the sink once);
// reconnects in a row without an answer are bounded, answered streams start the count
// anew; a lost mesh is uploaded again once and its units sent again.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "skinserve/client/frame_stream.h"
#include "skinserve/client/tick.h"

namespace skinserve::client {
namespace {

// What the fake does with a request it read.
enum class Act { kAnswer, kBreak };

// The value the fake puts in unit `frame`'s first position (checked by the sink).
float Marker(uint64_t frame) { return 0.5f + static_cast<float>(frame); }

v1::SkinResponse VertexPart(uint64_t frame) {
  v1::SkinResponse part;
  part.set_frame(frame);
  part.set_total_vertices(1);
  part.set_vertex_count(1);
  part.set_instances(1);
  const float positions[3] = {Marker(frame), 0.0f, 0.0f};
  part.set_positions(positions, sizeof positions);
  return part;
}

v1::SkinResponse NotFoundPart(uint64_t frame) {
  v1::SkinResponse part;
  part.set_frame(frame);
  part.mutable_error()->set_code(grpc::StatusCode::NOT_FOUND);
  part.mutable_error()->set_message("mesh 'mesh' not found (fake)");
  part.set_last(true);
  return part;
}

class FakeSkinning final : public v1::Skinning::Service {
 public:
  // Decides for each request read: `stream` counts StreamSkin calls from 0, `answered` the
  // requests this stream answered so far.
  std::function<Act(int stream, int answered)> rule = [](int, int) { return Act::kAnswer; };
  std::atomic<bool> mesh_present{true};
  grpc::Status upload_status;
  std::atomic<int> streams{0}, uploads{0};

  grpc::Status StreamSkin(
      grpc::ServerContext*,
      grpc::ServerReaderWriter<v1::SkinResponse, v1::SkinRequest>* stream) override {
    const int index = streams++;
    int answered = 0;
    v1::SkinRequest request;
    while (stream->Read(&request)) {
      if (rule(index, answered) == Act::kBreak) {
        return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the fake replica went away");
      }
      for (const v1::SkinResponse& part : Answer(request)) stream->Write(part);
      ++answered;
    }
    return grpc::Status::OK;
  }

  grpc::Status UploadMesh(grpc::ServerContext*, grpc::ServerReader<v1::UploadMeshRequest>* reader,
                          v1::MeshInfo*) override {
    v1::UploadMeshRequest chunk;
    while (reader->Read(&chunk)) {
    }
    ++uploads;
    if (upload_status.ok()) mesh_present = true;
    return upload_status;
  }

 private:
  std::vector<v1::SkinResponse> Answer(const v1::SkinRequest& request) const {
    const bool found = mesh_present;
    if (request.characters_size() == 0) {  // a frame
      v1::SkinResponse part = found ? VertexPart(request.frame()) : NotFoundPart(request.frame());
      part.set_last(true);
      return {part};
    }
    std::vector<v1::SkinResponse> parts;  // a tick: characters' parts, then the final part
    v1::SkinResponse final_part;
    final_part.set_frame(request.frame());
    final_part.set_last(true);
    for (int c = 0; c < request.characters_size(); ++c) {
      v1::SkinResponse* header = final_part.mutable_tick()->add_characters();
      header->set_character(static_cast<uint32_t>(c));
      if (!found) {
        *header->mutable_error() = NotFoundPart(request.frame()).error();
        continue;
      }
      parts.push_back(VertexPart(request.frame()));
      parts.back().set_character(static_cast<uint32_t>(c));
      header->set_total_vertices(1);
      header->set_instances(1);
      header->set_last(true);
    }
    parts.push_back(final_part);
    return parts;
  }
};

// One run's outcome, the same for frames and ticks.
struct Outcome {
  Status status;
  std::map<uint64_t, int> delivered;     // unit -> times it reached the sink
  std::map<uint64_t, StatusCode> codes;  // unit -> its (last) status code
  std::vector<std::string> wrong;        // answered units whose vertices are not theirs
  uint64_t sent = 0, answered = 0, failed = 0, reconnects = 0, reuploads = 0;
  uint64_t settled = 0;  // units the summary counts answered or failed

  void Deliver(uint64_t frame, const Status& outcome, const std::vector<float>& positions) {
    ++delivered[frame];
    codes[frame] = outcome.code();
    if (outcome.ok() && (positions.size() != 3 || positions[0] != Marker(frame))) {
      wrong.push_back("unit " + std::to_string(frame));
    }
  }
  std::vector<uint64_t> Failed() const {
    std::vector<uint64_t> units;
    for (const auto& [frame, code] : codes) {
      if (code != StatusCode::kOk) units.push_back(frame);
    }
    return units;
  }
};

struct Limits {
  uint64_t units = 8;
  int window = 4;
  int max_reconnects = 3;
};

class StreamSessionTest : public ::testing::TestWithParam<bool> {
 protected:
  StreamSessionTest() {
    // On a loopback port: the in-process transport stalls a sync stream's first write.
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(&fake_);
    server_ = builder.BuildAndStart();
    client_ = std::make_unique<SkinClient>(grpc::CreateChannel("127.0.0.1:" + std::to_string(port),
                                                               grpc::InsecureChannelCredentials()));
    auto mesh = std::make_shared<MeshArrays>();
    mesh->vertex_count = 1;
    mesh->influences = 1;
    mesh->joint_count = 1;
    mesh->positions = {0, 0, 0};
    mesh->joints = {0};
    mesh->weights = {1};
    client_->Remember("mesh", mesh);
  }
  ~StreamSessionTest() override { server_->Shutdown(); }

  bool ticks() const { return GetParam(); }

  Outcome Stream(const Limits& limits) {
    return ticks() ? StreamTheTicks(limits) : StreamTheFrames(limits);
  }

  Outcome StreamTheFrames(const Limits& limits) {
    Outcome run;
    StreamSummary summary;
    run.status = StreamFrames(
        *client_,
        {.mesh_id = "mesh",
         .frames = limits.units,
         .window = limits.window,
         .max_reconnects = limits.max_reconnects},
        [this](uint64_t) { return std::span<const float>(palette_); },
        [&](FrameResult& r, std::chrono::nanoseconds) {
          run.Deliver(r.frame, r.status, r.positions);
        },
        &summary);
    run.sent = summary.sent, run.answered = summary.answered, run.failed = summary.failed;
    run.reconnects = summary.reconnects, run.reuploads = summary.reuploads;
    run.settled = summary.answered + summary.failed;
    return run;
  }

  Outcome StreamTheTicks(const Limits& limits) {
    Outcome run;
    TickStreamSummary summary;
    run.status = StreamTicks(
        *client_,
        {.ticks = limits.units, .window = limits.window, .max_reconnects = limits.max_reconnects},
        [this](uint64_t, Tick* tick) { tick->Add("mesh", palette_); },
        [&](TickResult& r, std::chrono::nanoseconds) {
          ASSERT_EQ(r.characters.size(), 1u);
          const FrameResult& c = r.characters[0];
          run.Deliver(r.frame, r.status.ok() ? c.status : r.status, c.positions);
        },
        &summary);
    // One character a tick: its counts are the units' (a tick whose character failed
    // counts as answered, a tick failed whole as failed).
    run.sent = summary.sent, run.answered = summary.characters_answered;
    run.failed = summary.characters_failed;
    run.reconnects = summary.reconnects, run.reuploads = summary.reuploads;
    run.settled = summary.answered + summary.failed;
    return run;
  }

  // Every unit of [0, units) reached the sink exactly once.
  static void ExpectEachDeliveredOnce(const Outcome& run, uint64_t units) {
    ASSERT_EQ(run.delivered.size(), units);
    for (const auto& [frame, times] : run.delivered) {
      EXPECT_LT(frame, units);
      EXPECT_EQ(times, 1) << "unit " << frame;
    }
    EXPECT_TRUE(run.wrong.empty()) << run.wrong.front();
    EXPECT_EQ(run.settled, units);
  }

  FakeSkinning fake_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<SkinClient> client_;
  std::vector<float> palette_ = std::vector<float>(12, 0.0f);
};

TEST_P(StreamSessionTest, AStreamBrokenBeforeItsFirstAnswerSendsItsUnitsOnTheNext) {
  fake_.rule = [](int stream, int) { return stream == 0 ? Act::kBreak : Act::kAnswer; };
  const Outcome run = Stream({});
  EXPECT_TRUE(run.status.ok()) << run.status.ToString();
  ExpectEachDeliveredOnce(run, 8);
  EXPECT_TRUE(run.Failed().empty());
  EXPECT_EQ(run.sent, 8u);
  EXPECT_EQ(run.answered, 8u);
  EXPECT_EQ(run.reconnects, 1u);
  EXPECT_EQ(fake_.streams, 2);
}

TEST_P(StreamSessionTest, AStreamBrokenAfterAnsweringFailsItsUnitsInFlightAndGoesOn) {
  // The first stream answers units 0 and 1, then breaks with units 2, 3 and perhaps more
  // (written while it was ending) in flight.
  fake_.rule = [](int stream, int answered) {
    return stream == 0 && answered == 2 ? Act::kBreak : Act::kAnswer;
  };
  const Outcome run = Stream({.units = 12});
  EXPECT_TRUE(run.status.ok()) << run.status.ToString();
  ExpectEachDeliveredOnce(run, 12);
  const std::vector<uint64_t> failed = run.Failed();
  ASSERT_GE(failed.size(), 2u);
  ASSERT_LE(failed.size(), 4u);  // the window
  for (std::size_t i = 0; i < failed.size(); ++i) {
    EXPECT_EQ(failed[i], 2 + i);
    EXPECT_EQ(run.codes.at(failed[i]), StatusCode::kUnavailable);
  }
  EXPECT_EQ(run.failed, failed.size());
  EXPECT_EQ(run.answered, 12 - failed.size());
  EXPECT_EQ(run.sent, 12u);  // the failed units are not sent again
  EXPECT_EQ(run.reconnects, 1u);
}

TEST_P(StreamSessionTest, ReconnectsInARowWithoutAnAnswerAreBounded) {
  fake_.rule = [](int, int) { return Act::kBreak; };
  const Outcome run = Stream({.window = 1, .max_reconnects = 2});
  EXPECT_EQ(run.status.code(), StatusCode::kUnavailable) << run.status.ToString();
  EXPECT_EQ(fake_.streams, 3);
  EXPECT_EQ(run.reconnects, 2u);
  // Unit 0 went on every stream and failed with the last.
  ExpectEachDeliveredOnce(run, 1);
  EXPECT_EQ(run.codes.at(0), StatusCode::kUnavailable);
  EXPECT_EQ(run.sent, 1u);
  EXPECT_EQ(run.failed, 1u);
}

TEST_P(StreamSessionTest, AStreamThatAnsweredStartsTheReconnectCountAnew) {
  // Every stream answers one unit and breaks at the next: 0 answered, 1 failed, 2
  // answered, ... With max_reconnects 1 the run only gets through if answers reset the count.
  fake_.rule = [](int, int answered) { return answered == 1 ? Act::kBreak : Act::kAnswer; };
  const Outcome run = Stream({.units = 7, .window = 1, .max_reconnects = 1});
  EXPECT_TRUE(run.status.ok()) << run.status.ToString();
  ExpectEachDeliveredOnce(run, 7);
  EXPECT_EQ(run.Failed(), (std::vector<uint64_t>{1, 3, 5}));
  EXPECT_EQ(run.reconnects, 3u);
  EXPECT_EQ(fake_.streams, 4);
}

TEST_P(StreamSessionTest, ALostMeshIsUploadedAgainOnceAndItsUnitsSentAgain) {
  fake_.mesh_present = false;
  const Outcome run = Stream({});
  EXPECT_TRUE(run.status.ok()) << run.status.ToString();
  ExpectEachDeliveredOnce(run, 8);
  EXPECT_TRUE(run.Failed().empty());
  // Units answered NOT_FOUND before the upload go again without another upload.
  EXPECT_EQ(fake_.uploads, 1);
  EXPECT_EQ(run.reuploads, 1u);
  EXPECT_EQ(run.sent, 8u);
}

TEST_P(StreamSessionTest, AFailedReuploadLeavesTheUnitNotFound) {
  fake_.mesh_present = false;
  fake_.upload_status = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "no (fake)");
  const Outcome run = Stream({.units = 1, .window = 1});
  EXPECT_TRUE(run.status.ok()) << run.status.ToString();
  ExpectEachDeliveredOnce(run, 1);
  EXPECT_EQ(run.codes.at(0), StatusCode::kNotFound);
  EXPECT_EQ(fake_.uploads, 1);
  EXPECT_EQ(run.reuploads, 0u);
}

INSTANTIATE_TEST_SUITE_P(FramesAndTicks, StreamSessionTest, ::testing::Bool(),
                         [](const auto& param) { return param.param ? "Ticks" : "Frames"; });

}  // namespace
}  // namespace skinserve::client
