// The caps on concurrent streams: --max-streams (StreamSkin streams over all connections,
// beyond it RESOURCE_EXHAUSTED naming the limit) and --max-streams-per-connection (HTTP/2
// MAX_CONCURRENT_STREAMS: a further call on the same connection waits until one ends).
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "own_connection.h"
#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using Stream = grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>;

v1::SkinRequest Frame(const std::string& mesh_id, uint64_t frame) {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  request.set_backend("serial");
  request.set_frame(frame);
  const std::vector<float> palette = MakeSyntheticPalette(77, 1, frame);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  return request;
}

// Sends one frame and reads its answer: afterwards the server has the stream open.
void ExchangeOne(Stream& stream, const std::string& mesh_id, uint64_t frame) {
  ASSERT_TRUE(stream.Write(Frame(mesh_id, frame)));
  v1::SkinResponse part;
  do {
    ASSERT_TRUE(stream.Read(&part));
    ASSERT_FALSE(part.has_error()) << part.error().message();
  } while (!part.last());
}

uint64_t OpenStreams(client::SkinClient& client) {
  auto stats = client.GetServerStats();
  EXPECT_TRUE(stats.ok()) << stats.status().ToString();
  return stats.ok() ? stats->open_streams() : 0;
}

TEST(StreamLimitsTest, StreamsBeyondMaxStreamsAreRefusedNamingTheLimit) {
  server::ServerOptions options;
  options.max_streams = 2;
  TestServer t(options);
  auto mesh = t.client->Upload(MakeSyntheticMesh({.vertex_count = 1000}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();

  // Two streams, each on a connection of its own, open and working.
  std::vector<std::unique_ptr<v1::Skinning::Stub>> stubs;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<Stream>> streams;
  for (int s = 0; s < 3; ++s) {
    stubs.push_back(v1::Skinning::NewStub(OwnConnection(t.target)));
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    streams.push_back(stubs.back()->StreamSkin(contexts.back().get()));
  }
  ExchangeOne(*streams[0], mesh->mesh_id(), 0);
  ExchangeOne(*streams[1], mesh->mesh_id(), 1);
  EXPECT_EQ(OpenStreams(*t.client), 2u);

  // The third is refused at once, and says which limit and how to change it.
  streams[2]->Write(Frame(mesh->mesh_id(), 2));
  v1::SkinResponse part;
  EXPECT_FALSE(streams[2]->Read(&part));
  const grpc::Status refused = streams[2]->Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(refused.error_message().find("--max-streams 2"), std::string::npos)
      << refused.error_message();

  // Once one ends, a new stream is accepted again. (The client may see its status before
  // the server has released the stream: wait until the server counts one.)
  ASSERT_TRUE(streams[0]->WritesDone());
  EXPECT_TRUE(streams[0]->Finish().ok());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (OpenStreams(*t.client) != 1 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(OpenStreams(*t.client), 1u);
  grpc::ClientContext again_context;
  auto again = stubs[2]->StreamSkin(&again_context);
  ExchangeOne(*again, mesh->mesh_id(), 3);
  ASSERT_TRUE(again->WritesDone());
  EXPECT_TRUE(again->Finish().ok());
  ASSERT_TRUE(streams[1]->WritesDone());
  EXPECT_TRUE(streams[1]->Finish().ok());
}

TEST(StreamLimitsTest, CallsBeyondThePerConnectionLimitWaitForOneToEnd) {
  server::ServerOptions options;
  options.max_streams_per_connection = 2;
  TestServer t(options);
  auto mesh = t.client->Upload(MakeSyntheticMesh({.vertex_count = 1000}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();

  auto stub = v1::Skinning::NewStub(OwnConnection(t.target));
  grpc::ClientContext first_context, second_context, third_context;
  auto first = stub->StreamSkin(&first_context);
  auto second = stub->StreamSkin(&second_context);
  ExchangeOne(*first, mesh->mesh_id(), 0);
  ExchangeOne(*second, mesh->mesh_id(), 1);

  // The third stream of this connection is held back by HTTP/2 until one of the two ends:
  // its frame is not answered meanwhile, and the server never sees a third stream.
  std::atomic<bool> third_answered{false};
  std::thread third_thread([&] {
    auto third = stub->StreamSkin(&third_context);
    ExchangeOne(*third, mesh->mesh_id(), 2);
    third_answered = true;
    EXPECT_TRUE(third->WritesDone());
    EXPECT_TRUE(third->Finish().ok());
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_FALSE(third_answered.load());
  EXPECT_EQ(OpenStreams(*t.client), 2u);  // the stats call goes over another connection

  ASSERT_TRUE(first->WritesDone());
  EXPECT_TRUE(first->Finish().ok());
  third_thread.join();
  EXPECT_TRUE(third_answered.load());
  ASSERT_TRUE(second->WritesDone());
  EXPECT_TRUE(second->Finish().ok());
}

TEST(StreamLimitsTest, OptionsHaveEnvironmentVariables) {
  server::ServerOptions options;
  CLI::App app;
  server::AddServerOptions(app, options);
  setenv("SKINSERVE_MAX_STREAMS", "7", 1);
  setenv("SKINSERVE_MAX_STREAMS_PER_CONNECTION", "3", 1);
  app.parse(std::vector<std::string>{});
  unsetenv("SKINSERVE_MAX_STREAMS");
  unsetenv("SKINSERVE_MAX_STREAMS_PER_CONNECTION");
  EXPECT_EQ(options.max_streams, 7u);
  EXPECT_EQ(options.max_streams_per_connection, 3);
}

}  // namespace
}  // namespace skinserve::testing
