// The limits on uploads (issue 27, item 1), through a real server on loopback: the caps on
// uploads open at once (--max-uploads over all connections, --max-uploads-per-connection),
// the upload budget (--upload-budget-mb) and the idle limit (--upload-idle-seconds). Each
// refusal is RESOURCE_EXHAUSTED naming the flag and its value, and leaves the mesh store
// as it was.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "skinserve/reference/synthetic.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;
using Writer = grpc::ClientWriter<v1::UploadMeshRequest>;

v1::UploadMeshRequest Header(uint32_t vertices) {
  v1::UploadMeshRequest message;
  message.mutable_header()->set_vertex_count(vertices);
  message.mutable_header()->set_influences(2);
  message.mutable_header()->set_joint_count(77);
  return message;
}

// An upload that sent its header and holds its stream open.
struct HeldUpload {
  grpc::ClientContext context;
  v1::MeshInfo info;
  std::unique_ptr<Writer> writer;

  HeldUpload(v1::Skinning::Stub& stub, uint32_t vertices = 1'000'000) {
    writer = stub.UploadMesh(&context, &info);
    writer->Write(Header(vertices));  // may fail: the server may have refused it already
  }
  // The status the server ended the upload with (blocks until it does).
  grpc::Status Finish() { return writer->Finish(); }
  grpc::Status Cancel() {
    context.TryCancel();
    return writer->Finish();
  }
};

v1::ServerStats Stats(client::SkinClient& client) {
  auto stats = client.GetServerStats();
  EXPECT_TRUE(stats.ok()) << stats.status().ToString();
  return stats.ok() ? *stats : v1::ServerStats();
}

// The client may see a call's status before the server has released it (or see its own
// call return before the server has admitted it): waits until the server counts `open`.
void WaitForOpenUploads(client::SkinClient& client, uint64_t open) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (Stats(client).open_uploads() != open && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_EQ(Stats(client).open_uploads(), open);
}

void ExpectRefused(const grpc::Status& status, const std::string& limit) {
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  EXPECT_NE(status.error_message().find(limit), std::string::npos) << status.error_message();
}

TEST(UploadLimitsTest, UploadsBeyondMaxUploadsAreRefusedNamingTheLimit) {
  server::ServerOptions options;
  options.max_uploads = 2;
  TestServer t(options);
  std::vector<std::unique_ptr<v1::Skinning::Stub>> stubs;
  for (int c = 1; c <= 3; ++c) {
    stubs.push_back(v1::Skinning::NewStub(client::MakeChannel(t.target, c)));
  }
  HeldUpload first(*stubs[0]), second(*stubs[1]);
  WaitForOpenUploads(*t.client, 2);

  HeldUpload third(*stubs[2]);
  ExpectRefused(third.Finish(), "--max-uploads 2");
  auto stats = Stats(*t.client);
  EXPECT_EQ(stats.rejected_uploads_max_uploads(), 1u);
  EXPECT_EQ(stats.meshes(), 0u);

  // Once one ends, an upload is admitted again and stores its mesh.
  EXPECT_EQ(first.Cancel().error_code(), grpc::StatusCode::CANCELLED);
  WaitForOpenUploads(*t.client, 1);
  EXPECT_TRUE(t.client->Upload(MakeSyntheticMesh({.vertex_count = 1000})).ok());
  EXPECT_EQ(Stats(*t.client).meshes(), 1u);
  second.Cancel();
  WaitForOpenUploads(*t.client, 0);
}

TEST(UploadLimitsTest, UploadsBeyondThePerConnectionCapAreRefusedOthersGoOn) {
  server::ServerOptions options;
  options.max_uploads_per_connection = 2;
  TestServer t(options);
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target, 1));
  HeldUpload first(*stub), second(*stub);
  WaitForOpenUploads(*t.client, 2);

  HeldUpload third(*stub);  // the same connection: refused
  ExpectRefused(third.Finish(), "--max-uploads-per-connection 2");
  // Another connection is not held back by this one's uploads.
  client::SkinClient other(client::MakeChannel(t.target, 2));
  auto stored = other.Upload(MakeSyntheticMesh({.vertex_count = 1000}));
  EXPECT_TRUE(stored.ok()) << stored.status().ToString();
  auto stats = Stats(*t.client);
  EXPECT_EQ(stats.rejected_uploads_per_connection(), 1u);
  EXPECT_EQ(stats.meshes(), 1u);
  first.Cancel();
  second.Cancel();
  WaitForOpenUploads(*t.client, 0);
}

// A re-upload refused for the connection's cap (other clients of the process sharing the
// connection are re-uploading: a replica that lacks the mesh loses it to all of them at
// once) waits and tries again, and succeeds once the cap lets it.
TEST(UploadLimitsTest, AReuploadRefusedForTheConnectionsCapWaitsAndTriesAgain) {
  server::ServerOptions options;
  options.max_uploads_per_connection = 1;
  TestServer t(options);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 1000});
  auto uploaded = t.client->Upload(arrays);
  ASSERT_TRUE(uploaded.ok()) << uploaded.status().ToString();
  ASSERT_TRUE(t.client->DeleteMesh(uploaded->mesh_id()).ok());
  // The client's own connection's one upload place, taken.
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  auto held = std::make_unique<HeldUpload>(*stub);
  WaitForOpenUploads(*t.client, 1);
  Status reuploaded;
  std::thread reupload([&] { reuploaded = t.client->Reupload(uploaded->mesh_id()); });
  std::this_thread::sleep_for(100ms);  // refused at least once meanwhile
  held->Cancel();
  reupload.join();
  EXPECT_TRUE(reuploaded.ok()) << reuploaded.ToString();
  EXPECT_GE(Stats(*t.client).rejected_uploads_per_connection(), 1u);
  EXPECT_TRUE(t.client->GetMesh(uploaded->mesh_id()).ok());
}

TEST(UploadLimitsTest, AnUploadBeyondTheBudgetIsRefusedAndItsMemoryReturned) {
  server::ServerOptions options;
  options.upload_budget_mb = 1;
  TestServer t(options);
  auto stats = Stats(*t.client);
  EXPECT_EQ(stats.upload_budget_bytes(), 1u << 20);

  // 100k vertices, 2 influences: 2 MB of arrays, more than the budget.
  auto refused = t.client->Upload(MakeSyntheticMesh({.vertex_count = 100'000}));
  EXPECT_EQ(refused.status().code(), StatusCode::kResourceExhausted) << refused.status().ToString();
  EXPECT_NE(refused.status().message().find("--upload-budget-mb 1"), std::string::npos)
      << refused.status().message();
  stats = Stats(*t.client);
  EXPECT_EQ(stats.meshes(), 0u);
  EXPECT_EQ(stats.rejected_uploads_budget(), 1u);
  WaitForOpenUploads(*t.client, 0);
  EXPECT_EQ(Stats(*t.client).upload_bytes(), 0u) << "the refused upload's charge is returned";

  // A mesh that fits goes through.
  EXPECT_TRUE(t.client->Upload(MakeSyntheticMesh({.vertex_count = 10'000})).ok());
  EXPECT_EQ(Stats(*t.client).meshes(), 1u);
}

TEST(UploadLimitsTest, AnUploadThatSendsNothingIsEndedAfterTheIdleLimit) {
  server::ServerOptions options;
  options.upload_idle_seconds = 1;
  TestServer t(options);
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target, 1));

  // A header, then silence: ended within the limit plus the watchdog's period.
  const auto start = std::chrono::steady_clock::now();
  HeldUpload silent(*stub);
  ExpectRefused(silent.Finish(), "--upload-idle-seconds 1");
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_GE(took, 900ms);
  EXPECT_LT(took, 5s);

  // An upload that sends a chunk more often than the limit is not idle, however long it
  // takes in all.
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 1000});
  grpc::ClientContext context;
  v1::MeshInfo info;
  auto writer = stub->UploadMesh(&context, &info);
  ASSERT_TRUE(writer->Write(Header(1000)));
  for (std::size_t part = 0; part < 4; ++part) {
    std::this_thread::sleep_for(400ms);
    v1::UploadMeshRequest chunk;
    chunk.mutable_chunk()->set_array(v1::MESH_ARRAY_POSITIONS);
    chunk.mutable_chunk()->set_offset(part * 750);
    chunk.mutable_chunk()->set_data(arrays.positions.data() + part * 750, 750 * sizeof(float));
    ASSERT_TRUE(writer->Write(chunk)) << "part " << part;
  }
  v1::UploadMeshRequest joints, weights;
  joints.mutable_chunk()->set_array(v1::MESH_ARRAY_JOINTS);
  joints.mutable_chunk()->set_data(arrays.joints.data(), arrays.joints.size() * sizeof(uint16_t));
  weights.mutable_chunk()->set_array(v1::MESH_ARRAY_WEIGHTS);
  weights.mutable_chunk()->set_data(arrays.weights.data(), arrays.weights.size() * sizeof(float));
  ASSERT_TRUE(writer->Write(joints));
  ASSERT_TRUE(writer->Write(weights));
  ASSERT_TRUE(writer->WritesDone());
  const grpc::Status stored = writer->Finish();
  EXPECT_TRUE(stored.ok()) << stored.error_message();

  auto stats = Stats(*t.client);
  EXPECT_EQ(stats.cancelled_uploads_idle(), 1u);
  EXPECT_EQ(stats.meshes(), 1u) << "only the complete upload is stored";
  WaitForOpenUploads(*t.client, 0);
  EXPECT_EQ(Stats(*t.client).upload_bytes(), 0u);
}

}  // namespace
}  // namespace skinserve::testing
