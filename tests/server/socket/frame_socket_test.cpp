// The frame socket (server/socket/, --frame-socket) through a real server: a client of this
// process registers regions over gRPC on the server's Unix socket and sends StreamSkin's
// requests over the frame socket (client::FrameSocketClient). Every answer is checked
// against the float64 reference: frames into a region on every backend and encoding,
// frames answered with their vertices (several parts), ticks; then the contract's edges: a
// bad frame fails alone, the limits end the connection naming them before anything is
// read or parsed, the budget refuses, a quiet connection ends, a drain answers what was
// read, one connection over the cap is refused, the greeting is checked.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <thread>

#include "skinserve/client/frame_socket_client.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/tick.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/frame_socket_protocol.h"
#include "skinserve/wire/raw_part.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using client::FrameResult;
using client::FrameSocketClient;
using client::RegionOutput;
using client::SharedMemoryRegion;

constexpr uint32_t kJoints = 77;  // MakeSyntheticMesh's default

class FrameSocketTest : public ::testing::Test {
 protected:
  void SetUp() override { Start({}); }
  void TearDown() override {
    t_.reset();
    std::filesystem::remove_all(dir_);
  }

  void Start(server::ServerOptions options) {
    t_.reset();
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
    char name[] = "/dev/shm/skinserve-fsock-XXXXXX";
    ASSERT_NE(mkdtemp(name), nullptr);
    dir_ = name;
    options.shm_dir = dir_;
    options.frame_socket = dir_ + "/frames.sock";
    t_ = std::make_unique<TestServer>(options, Transport::kUnixSocket);
  }

  std::unique_ptr<FrameSocketClient> Connect() {
    auto socket = FrameSocketClient::Connect(dir_ + "/frames.sock");
    EXPECT_TRUE(socket.ok()) << socket.status().ToString();
    return socket.ok() ? std::move(socket).value() : nullptr;
  }

  std::string Upload(uint32_t vertices, uint64_t seed) {
    MeshArrays arrays = MakeSyntheticMesh(
        {.vertex_count = vertices, .influences = 2, .normals = true, .seed = seed});
    auto info = t_->client->Upload(arrays);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    meshes_[info->mesh_id()] = Mesh::Create(arrays).value();
    return info->mesh_id();
  }

  SharedMemoryRegion& Region(const std::string& name, uint64_t bytes) {
    auto region = SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("fsock"), bytes, dir_);
    EXPECT_TRUE(region.ok()) << region.status().ToString();
    regions_[name] = std::move(region).value();
    EXPECT_TRUE(t_->client->RegisterRegion(name, *regions_[name]).ok());
    return *regions_[name];
  }

  v1::SkinRequest Frame(const std::string& mesh_id, const std::string& backend, uint64_t frame,
                        VertexEncoding encoding = VertexEncoding::kFloat32,
                        const std::string& region = "") {
    v1::SkinRequest request;
    request.set_mesh_id(mesh_id);
    request.set_backend(backend);
    request.set_frame(frame);
    request.set_want_normals(true);
    request.set_encoding(static_cast<v1::Encoding>(encoding));
    request.set_palette(wire::EncodeFloats(MakeSyntheticPalette(kJoints, 5, frame)));
    if (!region.empty()) request.mutable_output()->set_region(region);
    return request;
  }

  // Reads one frame's answer (its parts until `last`); the status Read ended with if the
  // connection ended first.
  FrameResult ReadFrame(FrameSocketClient& socket, const std::string& region = "") {
    RegionOutput output;
    if (!region.empty()) output = {.name = region, .region = regions_.at(region).get()};
    client::FrameAssembler assembler(region.empty() ? nullptr : &output);
    FrameResult result;
    wire::RawPart reader;
    grpc::ByteBuffer part;
    while (true) {
      if (!socket.Read(&part)) {
        result.status = socket.Finish();
        ADD_FAILURE() << "the connection ended before the answer: " << result.status.ToString();
        return result;
      }
      if (assembler.Add(part, &reader, &result)) return result;
    }
  }

  // The answer of frame `frame` of `mesh_id` (its palette MakeSyntheticPalette's of that
  // frame) against the float64 reference; its number is `answered_as` (a tick character's:
  // the tick's), by default `frame`.
  void ExpectReference(FrameResult r, const std::string& mesh_id, uint64_t frame,
                       VertexEncoding encoding, const std::string& what,
                       std::optional<uint64_t> answered_as = std::nullopt) {
    ASSERT_TRUE(r.status.ok()) << what << ": " << r.status.ToString();
    ASSERT_TRUE(client::DecodeRegionFrame(&r).ok()) << what;
    const Mesh& mesh = *meshes_.at(mesh_id);
    ASSERT_EQ(r.vertices, mesh.vertex_count()) << what;
    EXPECT_EQ(r.frame, answered_as.value_or(frame)) << what;
    const auto palette = MakeSyntheticPalette(kJoints, 5, frame);
    const EncodedDeviation d = CompareEncodedWithReference(
        mesh, palette, encoding, r.bounds.empty() ? Bounds{} : r.bounds[0], r.instance_positions(0),
        r.instance_normals(0));
    EXPECT_TRUE(d.within_tolerance()) << what << ": worst position ratio " << d.worst_position_ratio
                                      << " at vertex " << d.worst_vertex;
  }

  // Sends raw bytes on a plain connection (greeting included or not), half-closes it and
  // returns the server's last message's status: the connection's end.
  Status RawEnd(const std::string& bytes) {
    const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr = {};
    addr.sun_family = AF_UNIX;
    const std::string path = dir_ + "/frames.sock";
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    EXPECT_EQ(connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0);
    EXPECT_EQ(send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(bytes.size()));
    shutdown(fd, SHUT_WR);  // nothing more comes
    std::string answer;
    char buffer[4096];
    for (ssize_t got; (got = recv(fd, buffer, sizeof(buffer), 0)) > 0;) answer.append(buffer, got);
    close(fd);
    if (answer.size() < 4) return Internal("no last message");
    uint32_t header = 0;
    for (int i = 0; i < 4; ++i) header |= static_cast<uint32_t>(uint8_t(answer[i])) << (8 * i);
    EXPECT_NE(header & wire::kFrameSocketEndBit, 0u) << "the only message is the last one";
    v1::SkinResponse end;
    EXPECT_TRUE(end.ParseFromString(answer.substr(4, header & wire::kFrameSocketSizeMask)));
    return wire::FromGrpc(
        grpc::Status(static_cast<grpc::StatusCode>(end.error().code()), end.error().message()));
  }

  static std::string Header(uint32_t size) {
    std::string h(4, '\0');
    for (int i = 0; i < 4; ++i) h[i] = static_cast<char>(size >> (8 * i));
    return h;
  }

  std::string dir_;
  std::unique_ptr<TestServer> t_;
  std::map<std::string, std::shared_ptr<const Mesh>> meshes_;
  std::map<std::string, std::unique_ptr<SharedMemoryRegion>> regions_;
};

TEST_F(FrameSocketTest, FramesIntoARegionMatchTheReferenceOnEveryBackendAndEncoding) {
  const std::string mesh = Upload(2531, 1);
  const VertexEncoding encodings[] = {VertexEncoding::kFloat32, VertexEncoding::kFloat16,
                                      VertexEncoding::kSnorm16};
  Region("r", wire::RegionFrameBytes(2531, 1, VertexEncoding::kFloat32, true));
  auto socket = Connect();
  ASSERT_NE(socket, nullptr);
  uint64_t frame = 0;
  for (const std::string& backend : SkinningBackends(*t_->client)) {
    for (VertexEncoding encoding : encodings) {
      for (int repeat = 0; repeat < 2; ++repeat, ++frame) {  // the second reuses the plan
        ASSERT_TRUE(socket->Write(Frame(mesh, backend, frame, encoding, "r")));
        const FrameResult r = ReadFrame(*socket, "r");
        EXPECT_TRUE(r.in_region()) << backend;
        ExpectReference(r, mesh, frame, encoding,
                        backend + " " + std::string(VertexEncodingName(encoding)));
      }
    }
  }
  socket->WritesDone();
  grpc::ByteBuffer part;
  EXPECT_FALSE(socket->Read(&part));
  EXPECT_TRUE(socket->Finish().ok()) << socket->Finish().ToString();
}

TEST_F(FrameSocketTest, FramesAnsweredWithTheirVerticesComeInPartsAndMatchTheReference) {
  // 120,000 vertices with normals: 2.9 MB of float32, several parts of at most 1 MiB.
  const std::string large = Upload(120'000, 2), small = Upload(777, 3);
  auto socket = Connect();
  ASSERT_NE(socket, nullptr);
  // Pipelined: every request first, then every answer, in order.
  const std::vector<std::pair<std::string, VertexEncoding>> frames = {
      {large, VertexEncoding::kFloat32},
      {small, VertexEncoding::kSnorm16},
      {large, VertexEncoding::kFloat16},
      {small, VertexEncoding::kFloat32}};
  for (std::size_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(socket->Write(Frame(frames[f].first, "simd", f, frames[f].second)));
  }
  for (std::size_t f = 0; f < frames.size(); ++f) {
    ExpectReference(ReadFrame(*socket), frames[f].first, f, frames[f].second,
                    "frame " + std::to_string(f));
  }
}

TEST_F(FrameSocketTest, ATickIsAnsweredWholeAndABadCharacterFailsAlone) {
  const std::string a = Upload(1500, 4), b = Upload(2200, 5);
  const uint64_t stride = wire::RegionFrameBytes(2200, 1, VertexEncoding::kFloat32, true);
  SharedMemoryRegion& region = Region("tick", 3 * stride);
  const auto pa = MakeSyntheticPalette(kJoints, 5, 7), pb = MakeSyntheticPalette(kJoints, 5, 8);
  client::Tick tick;
  tick.set_frame(42);
  tick.Add(a, pa, {.want_normals = true});  // vertices in the answer
  tick.Add(std::string(64, 'e'), pa, {});   // no such mesh
  tick.Add(b, pb,
           {.want_normals = true, .output = {.name = "tick", .region = &region, .offset = stride}});
  v1::SkinRequest request;
  tick.ToWire(&request);
  auto socket = Connect();
  ASSERT_NE(socket, nullptr);
  ASSERT_TRUE(socket->Write(request));
  client::TickResult result;
  client::TickAssembler assembler(tick, &result);
  wire::RawPart reader;
  grpc::ByteBuffer part;
  bool complete = false;
  while (!complete && socket->Read(&part)) complete = assembler.Add(part, &reader);
  ASSERT_TRUE(complete) << socket->Finish().ToString();
  EXPECT_EQ(result.frame, 42u);
  ASSERT_EQ(result.characters.size(), 3u);
  ExpectReference(result.characters[0], a, 7, VertexEncoding::kFloat32, "character 0", 42);
  EXPECT_EQ(result.characters[1].status.code(), StatusCode::kNotFound)
      << result.characters[1].status.ToString();
  EXPECT_NE(result.characters[1].status.message().find("character 1"), std::string::npos);
  EXPECT_TRUE(result.characters[2].in_region());
  ExpectReference(result.characters[2], b, 8, VertexEncoding::kFloat32, "character 2", 42);
}

TEST_F(FrameSocketTest, ABadFrameFailsAloneAndTheConnectionGoesOn) {
  const std::string mesh = Upload(1000, 6);
  Region("r", wire::RegionFrameBytes(1000, 1, VertexEncoding::kFloat32, true));
  auto socket = Connect();
  ASSERT_NE(socket, nullptr);
  v1::SkinRequest short_palette = Frame(mesh, "simd", 1, VertexEncoding::kFloat32, "r");
  short_palette.mutable_palette()->resize(12 * 4 * (kJoints - 1));
  v1::SkinRequest unknown_region = Frame(mesh, "simd", 2, VertexEncoding::kFloat32, "nope");
  v1::SkinRequest unknown_mesh = Frame(std::string(64, 'd'), "simd", 3);
  ASSERT_TRUE(socket->Write(short_palette));
  ASSERT_TRUE(socket->Write(unknown_region));
  ASSERT_TRUE(socket->Write(unknown_mesh));
  ASSERT_TRUE(socket->Write(Frame(mesh, "simd", 4, VertexEncoding::kFloat32, "r")));
  const FrameResult r1 = ReadFrame(*socket, "r");
  EXPECT_EQ(r1.status.code(), StatusCode::kInvalidArgument) << r1.status.ToString();
  EXPECT_NE(r1.status.message().find("palette"), std::string::npos) << r1.status.ToString();
  const FrameResult r2 = ReadFrame(*socket);
  EXPECT_FALSE(r2.status.ok());
  EXPECT_NE(r2.status.message().find("'nope'"), std::string::npos) << r2.status.ToString();
  const FrameResult r3 = ReadFrame(*socket);
  EXPECT_EQ(r3.status.code(), StatusCode::kNotFound) << r3.status.ToString();
  ExpectReference(ReadFrame(*socket, "r"), mesh, 4, VertexEncoding::kFloat32, "after the errors");
}

TEST_F(FrameSocketTest, ARequestOverTheLimitEndsTheConnectionBeforeItIsRead) {
  const std::string hello(wire::kFrameSocketHello);
  // 65 MiB announced, nothing of it sent: refused on the header alone.
  Status s = RawEnd(hello + Header(65u << 20));
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted) << s.ToString();
  EXPECT_NE(s.message().find("--max-tick-bytes"), std::string::npos) << s.ToString();
  s = RawEnd("SKFRAME0" + Header(4) + "abcd");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("SKFRAME1"), std::string::npos) << s.ToString();
  s = RawEnd(hello + Header(4) + std::string("\xff\xff\xff\xff", 4));  // no SkinRequest
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("not a valid skinserve.v1.SkinRequest"), std::string::npos)
      << s.ToString();
  s = RawEnd(hello + Header(100) + "short");  // the client closes mid-message
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("in the middle of a message"), std::string::npos) << s.ToString();
}

TEST_F(FrameSocketTest, TheInFlightBudgetRefusesARequestBeforeItsBytesAreTaken) {
  server::ServerOptions options;
  options.inflight_budget_mb = 1;
  Start(options);
  // 3 MiB announced (under the 4 MiB a frame may hold): the budget of 1 MiB cannot hold it.
  const Status s = RawEnd(std::string(wire::kFrameSocketHello) + Header(3u << 20));
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted) << s.ToString();
  EXPECT_NE(s.message().find("--inflight-budget-mb"), std::string::npos) << s.ToString();
}

TEST_F(FrameSocketTest, AQuietConnectionEndsAndADrainAnswersWhatWasRead) {
  server::ServerOptions options;
  options.stream_idle_seconds = 0.3;
  Start(options);
  const std::string mesh = Upload(900, 7);
  auto quiet = Connect();
  ASSERT_NE(quiet, nullptr);
  ASSERT_TRUE(quiet->Write(Frame(mesh, "simd", 11)));
  ExpectReference(ReadFrame(*quiet), mesh, 11, VertexEncoding::kFloat32, "before the quiet");
  grpc::ByteBuffer part;
  EXPECT_FALSE(quiet->Read(&part));  // nothing sent for 0.3 s
  EXPECT_EQ(quiet->Finish().code(), StatusCode::kUnavailable) << quiet->Finish().ToString();
  EXPECT_NE(quiet->Finish().message().find("--stream-idle-seconds"), std::string::npos);
  EXPECT_NE(quiet->Finish().message().find("frame 11"), std::string::npos);

  auto draining = Connect();
  ASSERT_NE(draining, nullptr);
  ASSERT_TRUE(draining->Write(Frame(mesh, "simd", 12)));
  ExpectReference(ReadFrame(*draining), mesh, 12, VertexEncoding::kFloat32, "before the drain");
  t_->server->Shutdown(std::chrono::milliseconds(2000));
  EXPECT_FALSE(draining->Read(&part));
  EXPECT_EQ(draining->Finish().code(), StatusCode::kUnavailable) << draining->Finish().ToString();
  EXPECT_NE(draining->Finish().message().find("shutting down"), std::string::npos);
  EXPECT_NE(draining->Finish().message().find("frame 12"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/frames.sock")) << "the socket file stays";
}

TEST_F(FrameSocketTest, AConnectionOverTheCapIsRefusedNamingTheOption) {
  server::ServerOptions options;
  options.frame_socket_max_connections = 2;
  Start(options);
  const std::string mesh = Upload(600, 8);
  auto first = Connect(), second = Connect();
  ASSERT_NE(first, nullptr);
  ASSERT_NE(second, nullptr);
  // Both served (so both are open on the server before the third comes).
  for (auto* s : {first.get(), second.get()}) {
    ASSERT_TRUE(s->Write(Frame(mesh, "simd", 1)));
    ExpectReference(ReadFrame(*s), mesh, 1, VertexEncoding::kFloat32, "an open connection");
  }
  auto third = Connect();
  ASSERT_NE(third, nullptr);
  grpc::ByteBuffer part;
  EXPECT_FALSE(third->Read(&part));
  EXPECT_EQ(third->Finish().code(), StatusCode::kResourceExhausted) << third->Finish().ToString();
  EXPECT_NE(third->Finish().message().find("--frame-socket-max-connections"), std::string::npos);
  // GetServerStats (and /metrics, the same snapshot) count them.
  auto stats = t_->client->GetServerStats();
  ASSERT_TRUE(stats.ok()) << stats.status().ToString();
  EXPECT_EQ(stats->frame_socket_connections(), 2u);
  EXPECT_EQ(stats->frame_socket_refused(), 1u);
  EXPECT_EQ(stats->frame_socket_requests(), 2u);
  // Once one ends, a new one is served.
  first->WritesDone();
  EXPECT_FALSE(first->Read(&part));
  first.reset();
  for (int attempt = 0; attempt < 50; ++attempt) {
    auto again = Connect();
    ASSERT_NE(again, nullptr);
    // Refused while the first one's thread is still finishing: its write or read fails.
    if (again->Write(Frame(mesh, "simd", 2)) && again->Read(&part)) return;  // served
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ADD_FAILURE() << "no new connection was served after one ended";
}

}  // namespace
}  // namespace skinserve::testing
