// Slow and silent clients against a real skinserve process (issue 42, item 3): uploads that
// hold their slots with empty chunks, an upload that makes tiny progress past the upload
// deadline, StreamSkin streams that send nothing, connections that never speak HTTP/2 or
// hold no call, and reflection streams that would each hold a thread. The server ends each
// with a status naming the option, while a well-behaved client keeps skinning on a
// connection of its own, every answer checked against the float64 reference. The limits
// are set to 1-2 s to keep it quick; times are asserted only as "did not hang" bounds.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <thread>

#include "own_connection.h"
#include "process_probe.h"
#include "server_child.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using Stream = grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>;

// Past this, a call the server should have ended is given up on by the client (its
// deadline): the test then fails on the status, instead of hanging.
constexpr auto kDidNotHang = 20s;

std::chrono::system_clock::time_point GiveUpAt() {
  return std::chrono::system_clock::now() + kDidNotHang;
}

void ExpectEnded(const grpc::Status& status, grpc::StatusCode code, const std::string& option) {
  EXPECT_EQ(status.error_code(), code) << status.error_message();
  EXPECT_NE(status.error_message().find(option), std::string::npos) << status.error_message();
}

// A small mesh as a well-behaved client sends it, and its frames checked against the
// float64 reference.
struct CheckedMesh {
  MeshArrays arrays;
  std::shared_ptr<const Mesh> mesh;
  explicit CheckedMesh(uint64_t seed)
      : arrays(MakeSyntheticMesh(
            {.vertex_count = 3000, .influences = 4, .normals = true, .seed = seed})),
        mesh(Mesh::Create(arrays).value()) {}
  bool Right(uint64_t frame, const std::vector<float>& positions) const {
    return CompareWithReference(*mesh, MakeSyntheticPalette(77, 3, frame), positions, {})
        .within_tolerance();
  }
};

// Uploads `mesh` and skins one frame of it; OK only if the answer is right.
Status UploadAndSkin(client::SkinClient& client, const CheckedMesh& mesh) {
  auto info = client.Upload(mesh.arrays);
  if (!info.ok()) return info.status();
  client::FrameResult result;
  Status status =
      client.Skin(info->mesh_id(), "serial", MakeSyntheticPalette(77, 3, 5), 5, false, &result);
  if (status.ok() && !mesh.Right(5, result.positions)) {
    status = Internal("skinned vertices differ from the reference");
  }
  return status;
}

// A well-behaved client on a connection of its own: uploads its mesh, then streams frames
// of it until stopped, each answer checked against the float64 reference.
class GoodClient {
 public:
  explicit GoodClient(const std::string& target) : mesh_(7), client_(OwnConnection(target)) {
    auto info = client_.Upload(mesh_.arrays);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    if (!info.ok()) return;
    thread_ = std::thread([this, id = info->mesh_id()] {
      status_ = client::StreamFrames(
          client_,
          {.mesh_id = id,
           .backend = "serial",
           .frames = 1'000'000,
           .window = 2,
           .max_reconnects = 0,
           .stop = &stop_},
          [](uint64_t f) { return MakeSyntheticPalette(77, 3, f); },
          [this](client::FrameResult& r, std::chrono::nanoseconds) {
            if (!r.status.ok()) {
              ++failed_;
            } else if (!mesh_.Right(r.frame, r.positions)) {
              ++wrong_;
            } else {
              correct_.fetch_add(1);
            }
          });
    });
  }
  ~GoodClient() { Stop(); }
  uint64_t correct() const { return correct_.load(); }
  // Stops streaming and checks that every frame came back right.
  void Stop() {
    if (!thread_.joinable()) return;
    stop_ = true;
    thread_.join();
    EXPECT_TRUE(status_.ok()) << status_.ToString();
    EXPECT_EQ(wrong_, 0u);
    EXPECT_EQ(failed_, 0u);
    EXPECT_GT(correct_.load(), 0u);
  }

 private:
  CheckedMesh mesh_;
  client::SkinClient client_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> correct_{0};
  uint64_t wrong_ = 0, failed_ = 0;
  Status status_;
  std::thread thread_;
};

// An upload on a connection of its own: a header for 1000 vertices, then chunk(i) every
// `interval` until the server ends it.
class DrippingUpload {
 public:
  using ChunkMaker = v1::UploadMeshRequest (*)(int i);
  DrippingUpload(const std::string& target, ChunkMaker chunk, std::chrono::milliseconds interval)
      : stub_(v1::Skinning::NewStub(OwnConnection(target))) {
    context_.set_deadline(GiveUpAt());
    writer_ = stub_->UploadMesh(&context_, &info_);
    thread_ = std::thread([this, chunk, interval] {
      v1::UploadMeshRequest header;
      header.mutable_header()->set_vertex_count(1000);
      header.mutable_header()->set_influences(2);
      header.mutable_header()->set_joint_count(77);
      if (writer_->Write(header)) {
        for (int i = 0;; ++i) {
          std::this_thread::sleep_for(interval);
          if (!writer_->Write(chunk(i))) break;
          chunks_sent_.fetch_add(1);
        }
      }
      status_ = writer_->Finish();
    });
  }
  ~DrippingUpload() { Join(); }
  // The status the server ended it with.
  const grpc::Status& Join() {
    if (thread_.joinable()) thread_.join();
    return status_;
  }
  int chunks_sent() const { return chunks_sent_.load(); }

 private:
  std::unique_ptr<v1::Skinning::Stub> stub_;
  grpc::ClientContext context_;
  v1::MeshInfo info_;
  std::unique_ptr<grpc::ClientWriter<v1::UploadMeshRequest>> writer_;
  std::atomic<int> chunks_sent_{0};
  grpc::Status status_;
  std::thread thread_;
};

v1::UploadMeshRequest EmptyChunk(int) {
  v1::UploadMeshRequest message;
  message.mutable_chunk()->set_array(v1::MESH_ARRAY_POSITIONS);
  return message;
}

// One vertex's position more each time: progress, however little.
v1::UploadMeshRequest OneMorePosition(int i) {
  const float xyz[3] = {0.5f, 0.25f, static_cast<float>(i)};
  v1::UploadMeshRequest message;
  message.mutable_chunk()->set_array(v1::MESH_ARRAY_POSITIONS);
  message.mutable_chunk()->set_offset(3 * static_cast<uint64_t>(i));
  message.mutable_chunk()->set_data(xyz, sizeof(xyz));
  return message;
}

class SlowClientsTest : public ::testing::Test {
 protected:
  // A server on serial with `limits` (flags) besides.
  void Start(const std::vector<std::string>& limits) {
    std::vector<std::string> args = {"--log-level", "warn",   "--threads",         "2",
                                     "--backends",  "serial", "--default-backend", "serial"};
    args.insert(args.end(), limits.begin(), limits.end());
    server_ = std::make_unique<ServerChild>(args);
    ASSERT_TRUE(server_->ready()) << server_->error();
    target_ = server_->target();
    stats_client_ = std::make_unique<client::SkinClient>(OwnConnection(target_));
  }
  v1::ServerStats Stats() {
    auto stats = stats_client_->GetServerStats();
    EXPECT_TRUE(stats.ok()) << stats.status().ToString();
    return stats.ok() ? *stats : v1::ServerStats();
  }
  // Waits (10 s at most) until `field` of the server's stats is `value`; true if it is.
  bool WaitForStat(uint64_t (v1::ServerStats::*field)() const, uint64_t value) {
    for (const auto until = Clock::now() + 10s; Clock::now() < until;
         std::this_thread::sleep_for(10ms)) {
      if ((Stats().*field)() == value) return true;
    }
    return (Stats().*field)() == value;
  }

  std::unique_ptr<ServerChild> server_;  // killed with the fixture
  std::string target_;
  std::unique_ptr<client::SkinClient> stats_client_;
};

TEST_F(SlowClientsTest, EmptyChunksDoNotKeepAnUploadSlot) {
  Start({"--max-uploads", "4", "--upload-idle-seconds", "2"});
  GoodClient good(target_);
  std::vector<std::unique_ptr<DrippingUpload>> drips;
  for (int i = 0; i < 4; ++i) {
    drips.push_back(std::make_unique<DrippingUpload>(target_, EmptyChunk, 250ms));
  }
  ASSERT_TRUE(WaitForStat(&v1::ServerStats::open_uploads, 4));
  const uint64_t answered_before = good.correct();

  // Every slot is taken: a fresh client's upload is refused...
  client::SkinClient fresh(OwnConnection(target_));
  const CheckedMesh mesh(11);
  const Status refused = UploadAndSkin(fresh, mesh);
  EXPECT_EQ(refused.code(), StatusCode::kResourceExhausted) << refused.ToString();
  EXPECT_NE(refused.message().find("--max-uploads 4"), std::string::npos) << refused.message();

  // ...until the idle limit ends the drips, although their empty chunks kept coming.
  for (auto& drip : drips) {
    ExpectEnded(drip->Join(), grpc::StatusCode::RESOURCE_EXHAUSTED, "--upload-idle-seconds 2");
    EXPECT_GE(drip->chunks_sent(), 2) << "the empty chunks did not flow";
  }
  EXPECT_GT(good.correct(), answered_before) << "nothing was skinned during the attack";
  ASSERT_TRUE(WaitForStat(&v1::ServerStats::open_uploads, 0));
  const Status stored = UploadAndSkin(fresh, mesh);
  EXPECT_TRUE(stored.ok()) << stored.ToString();

  good.Stop();
  const v1::ServerStats stats = Stats();
  EXPECT_EQ(stats.cancelled_uploads_idle(), 4u);
  EXPECT_EQ(stats.rejected_uploads_max_uploads(), 1u);
  EXPECT_EQ(stats.upload_bytes(), 0u);
}

TEST_F(SlowClientsTest, AnUploadThatKeepsProgressingEndsAtTheUploadDeadline) {
  Start({"--upload-idle-seconds", "1", "--upload-deadline-seconds", "2"});
  GoodClient good(target_);
  const uint64_t answered_before = good.correct();
  // Progress every 200 ms, well inside the idle limit: only the deadline can end it.
  DrippingUpload creeping(target_, OneMorePosition, 200ms);
  ExpectEnded(creeping.Join(), grpc::StatusCode::RESOURCE_EXHAUSTED, "--upload-deadline-seconds 2");
  EXPECT_GE(creeping.chunks_sent(), 2) << "the upload did not progress";
  EXPECT_GT(good.correct(), answered_before) << "nothing was skinned meanwhile";

  // An upload that finishes within the deadline is stored, and skins right.
  client::SkinClient fresh(OwnConnection(target_));
  const Status stored = UploadAndSkin(fresh, CheckedMesh(12));
  EXPECT_TRUE(stored.ok()) << stored.ToString();

  good.Stop();
  const v1::ServerStats stats = Stats();
  EXPECT_EQ(stats.cancelled_uploads_deadline(), 1u);
  EXPECT_EQ(stats.cancelled_uploads_idle(), 0u) << "its progress kept the idle clock back";
  EXPECT_TRUE(WaitForStat(&v1::ServerStats::upload_bytes, 0));
}

v1::SkinRequest Frame(const std::string& mesh_id, uint64_t frame) {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  request.set_backend("serial");
  request.set_frame(frame);
  const std::vector<float> palette = MakeSyntheticPalette(77, 3, frame);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  return request;
}

// Sends frame `frame` on `stream` and reads its answer; true if it is right.
bool ExchangeFrame(Stream& stream, const std::string& mesh_id, const CheckedMesh& mesh,
                   uint64_t frame) {
  if (!stream.Write(Frame(mesh_id, frame))) return false;
  v1::SkinResponse part;
  std::vector<float> positions;
  do {
    if (!stream.Read(&part) || part.has_error()) return false;
    const auto& bytes = part.positions();
    const std::size_t at = positions.size();
    positions.resize(at + bytes.size() / sizeof(float));
    std::memcpy(positions.data() + at, bytes.data(), bytes.size());
  } while (!part.last());
  return part.frame() == frame && mesh.Right(frame, positions);
}

// A StreamSkin stream on a connection of its own.
struct OwnStream {
  std::unique_ptr<v1::Skinning::Stub> stub;
  grpc::ClientContext context;
  std::unique_ptr<Stream> stream;
  explicit OwnStream(const std::string& target)
      : stub(v1::Skinning::NewStub(OwnConnection(target))) {
    context.set_deadline(GiveUpAt());
    stream = stub->StreamSkin(&context);
  }
  // Reads until the server ends the stream; its status.
  grpc::Status AwaitEnd() {
    v1::SkinResponse part;
    while (stream->Read(&part)) {
    }
    return stream->Finish();
  }
};

TEST_F(SlowClientsTest, SilentStreamsAreEndedSlowOnesAreNot) {
  Start({"--stream-idle-seconds", "1"});
  GoodClient good(target_);
  const CheckedMesh mesh(13);
  auto info = stats_client_->Upload(mesh.arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  const std::string id = info->mesh_id();

  OwnStream mute(target_);    // sends nothing at all
  OwnStream paused(target_);  // one frame, then nothing
  ASSERT_TRUE(ExchangeFrame(*paused.stream, id, mesh, 0));
  // A frame every 400 ms, for more than twice the limit: under the limit between frames.
  std::thread slow([&] {
    OwnStream s(target_);
    for (uint64_t f = 0; f < 8; ++f) {
      if (f > 0) std::this_thread::sleep_for(400ms);
      EXPECT_TRUE(ExchangeFrame(*s.stream, id, mesh, f)) << "frame " << f;
    }
    EXPECT_TRUE(s.stream->WritesDone());
    const grpc::Status finished = s.stream->Finish();
    EXPECT_TRUE(finished.ok()) << finished.error_message();
  });
  const uint64_t answered_before = good.correct();

  // UNAVAILABLE: every frame sent was answered, a new stream may carry on.
  ExpectEnded(mute.AwaitEnd(), grpc::StatusCode::UNAVAILABLE, "--stream-idle-seconds 1");
  const grpc::Status ended = paused.AwaitEnd();
  ExpectEnded(ended, grpc::StatusCode::UNAVAILABLE, "--stream-idle-seconds 1");
  EXPECT_NE(ended.error_message().find("the last read was frame 0"), std::string::npos)
      << ended.error_message();
  slow.join();
  EXPECT_GT(good.correct(), answered_before) << "nothing was skinned meanwhile";

  // The client that was cut off carries on with a new stream on the same connection.
  grpc::ClientContext again_context;
  auto again = paused.stub->StreamSkin(&again_context);
  EXPECT_TRUE(ExchangeFrame(*again, id, mesh, 1));
  EXPECT_TRUE(again->WritesDone());
  EXPECT_TRUE(again->Finish().ok());

  good.Stop();
  EXPECT_EQ(Stats().ended_streams_idle(), 2u);
  EXPECT_TRUE(WaitForStat(&v1::ServerStats::open_streams, 0));
}

// Reads what the server sends on `fd` (its HTTP/2 settings, a GOAWAY) until it closes the
// connection, within kDidNotHang; true if it did.
bool ClosedByPeer(int fd) {
  const auto until = Clock::now() + kDidNotHang;
  for (char bytes[256];;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    pollfd p{.fd = fd, .events = POLLIN, .revents = 0};
    if (left.count() <= 0 || poll(&p, 1, static_cast<int>(left.count())) != 1) return false;
    if (recv(fd, bytes, sizeof(bytes), 0) <= 0) return true;
  }
}

TEST_F(SlowClientsTest, ConnectionsThatNeverSpeakAreDropped) {
  // No idle limit: it would close the connection too, once gRPC has set it up.
  Start({"--handshake-timeout-seconds", "1", "--connection-idle-seconds", "0"});
  GoodClient good(target_);
  // A TCP connection that never sends HTTP/2's preface and settings.
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(std::stoi(target_.substr(target_.find(':') + 1))));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  EXPECT_TRUE(ClosedByPeer(fd)) << "a silent TCP connection was kept";
  close(fd);
  good.Stop();
}

TEST_F(SlowClientsTest, ConnectionsWithNoCallAreClosed) {
  Start({"--connection-idle-seconds", "1"});
  GoodClient good(target_);  // its connection always has a call open: never idle
  // A gRPC connection with no call gets a GOAWAY (the channel goes IDLE), and the
  // client's next call connects again.
  auto channel = OwnConnection(target_);
  ASSERT_TRUE(channel->WaitForConnected(GiveUpAt()));
  const auto until = Clock::now() + kDidNotHang;
  while (channel->GetState(false) == GRPC_CHANNEL_READY && Clock::now() < until) {
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_NE(channel->GetState(false), GRPC_CHANNEL_READY) << "an idle connection was kept";
  client::SkinClient again(channel);
  const Status answered = UploadAndSkin(again, CheckedMesh(14));
  EXPECT_TRUE(answered.ok()) << answered.ToString();
  good.Stop();
}

// The server's threads now (/proc/PID/status).
int Threads(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("Threads:", 0) == 0) return std::stoi(line.substr(8));
  }
  return -1;
}

// A reflection stream (gRPC's synchronous service: one thread each while open) that asked
// for the service list; `answered` if the server answered rather than refused it.
struct ReflectionStream {
  grpc::ClientContext context;
  std::unique_ptr<grpc::ClientReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>> call;
  bool answered = false;
  ReflectionStream(const std::shared_ptr<grpc::Channel>& channel) {
    static const grpc::internal::RpcMethod rpc(
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
        grpc::internal::RpcMethod::BIDI_STREAMING);
    context.set_deadline(GiveUpAt());
    call.reset(
        grpc::internal::ClientReaderWriterFactory<grpc::ByteBuffer, grpc::ByteBuffer>::Create(
            channel.get(), rpc, &context));
    const char list_services[] = {0x3a, 0x00};  // field 7, ""
    grpc::Slice slice(list_services, sizeof(list_services));
    grpc::ByteBuffer response;
    answered = call->Write(grpc::ByteBuffer(&slice, 1)) && call->Read(&response);
  }
  grpc::Status End() {
    call->WritesDone();
    grpc::ByteBuffer response;
    while (call->Read(&response)) {
    }
    return call->Finish();
  }
};

TEST_F(SlowClientsTest, ReflectionStreamsCannotTakeAThreadEach) {
  Start({});
  GoodClient good(target_);
  const int threads_before = Threads(server_->pid());
  auto channel = OwnConnection(target_);
  std::vector<std::unique_ptr<ReflectionStream>> streams;
  int answered = 0;
  for (int i = 0; i < 64; ++i) {
    streams.push_back(std::make_unique<ReflectionStream>(channel));
    answered += streams.back()->answered ? 1 : 0;
  }
  const int threads_held = Threads(server_->pid());
  std::printf("reflection streams: %d of 64 answered; server threads %d before, %d with them\n",
              answered, threads_before, threads_held);
  EXPECT_GT(answered, 0);
  EXPECT_LE(answered, 32) << "more reflection streams open than gRPC's thread quota";
  EXPECT_LE(threads_held, threads_before + 32 + 4) << "a thread per reflection stream";
  int refused = 0;
  for (auto& s : streams) {
    const grpc::Status status = s->End();
    if (s->answered) {
      EXPECT_TRUE(status.ok()) << status.error_message();
    } else {
      EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED)
          << status.error_message();
      ++refused;
    }
  }
  EXPECT_EQ(answered + refused, 64);
  // Once they are gone, reflection answers again.
  EXPECT_TRUE(ReflectionStream(channel).answered);
  good.Stop();
}

TEST(SlowClientsOptionsTest, OptionsHaveEnvironmentVariables) {
  const std::string help = RunAndCapture(std::string(SKINSERVE_SERVER_BINARY) + " --help");
  for (const char* variable : {"SKINSERVE_UPLOAD_DEADLINE_SECONDS", "SKINSERVE_STREAM_IDLE_SECONDS",
                               "SKINSERVE_CONNECTION_IDLE_SECONDS",
                               "SKINSERVE_HANDSHAKE_TIMEOUT_SECONDS", "SKINSERVE_GRPC_MEMORY_MB"}) {
    EXPECT_NE(help.find(variable), std::string::npos) << variable;
  }
}

}  // namespace
}  // namespace skinserve::testing
