// The same-host data plane through a real server (in this process) and the real client
// library: every backend, encoding and crowd size writes into a client's region exactly
// what the float64 reference allows and nothing outside the frame's range; every hostile
// case gets its status naming the region and the limit, and leaves the stream and the
// server serving; unregistering waits for the frames in flight; idle regions go.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include "skinserve/client/frame_stream.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using client::FrameResult;
using client::RegionOutput;
using client::SharedMemoryRegion;

constexpr std::byte kCanary{0xA5};

// A fresh directory under /dev/shm (real shared memory) as the server's --shm-dir.
class ShmDir {
 public:
  ShmDir() {
    char name[] = "/dev/shm/skinserve-test-XXXXXX";
    path_ = mkdtemp(name);
  }
  ~ShmDir() { std::filesystem::remove_all(path_); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

server::ServerOptions ShmOptions(const ShmDir& dir) {
  server::ServerOptions options;
  options.shm_dir = dir.path();
  return options;
}

std::unique_ptr<SharedMemoryRegion> MakeRegion(const ShmDir& dir, uint64_t bytes) {
  auto region =
      SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("test"), bytes, dir.path());
  EXPECT_TRUE(region.ok()) << region.status().ToString();
  std::memset(region.value()->bytes().data(), static_cast<int>(kCanary), bytes);
  return std::move(region).value();
}

// Every byte of `region` outside [begin, end) still holds the canary.
void ExpectUntouchedOutside(const SharedMemoryRegion& region, uint64_t begin, uint64_t end,
                            const std::string& what) {
  const auto bytes = region.bytes();
  uint64_t touched = 0;
  for (uint64_t i = 0; i < bytes.size(); ++i) {
    if ((i < begin || i >= end) && bytes[i] != kCanary) ++touched;
  }
  EXPECT_EQ(touched, 0u) << what << ": bytes outside [" << begin << ", " << end << ") changed";
}

std::vector<float> CrowdPalettes(uint32_t joints, uint32_t instances, uint64_t frame) {
  std::vector<float> palettes;
  for (uint32_t i = 0; i < instances; ++i) {
    const auto one = MakeSyntheticPalette(joints, 11 + i, frame + i);
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  return palettes;
}

// Each instance of a frame in a region, decoded, against the float64 reference within the
// bound of its encoding.
void ExpectRegionMatchesReference(const Mesh& mesh, const std::vector<float>& palettes,
                                  FrameResult result, bool normals, SkinningMethod method,
                                  const std::string& what) {
  ASSERT_TRUE(result.status.ok()) << what << ": " << result.status.ToString();
  ASSERT_TRUE(result.in_region()) << what;
  ASSERT_EQ(result.region_normals.empty(), !normals) << what;
  if (result.encoding == VertexEncoding::kFloat32) {  // read in place
    for (uint32_t k = 0; k < result.instances; ++k) {
      EXPECT_EQ(result.region_floats(false, k).size(), 3ull * mesh.vertex_count()) << what;
    }
  }
  ASSERT_TRUE(client::DecodeRegionFrame(&result).ok()) << what;
  const std::size_t floats = kFloatsPerJoint * mesh.joint_count();
  for (uint32_t k = 0; k < result.instances; ++k) {
    const std::span<const float> palette(palettes.data() + k * floats, floats);
    const EncodedDeviation d = CompareEncodedWithReference(
        mesh, palette, result.encoding, result.bounds[k], result.instance_positions(k),
        normals ? result.instance_normals(k) : std::span<const float>(), method);
    EXPECT_TRUE(d.within_tolerance())
        << what << " instance " << k << ": worst position ratio " << d.worst_position_ratio
        << ", normal ratio " << d.worst_normal_ratio << " at vertex " << d.worst_vertex;
  }
}

TEST(SharedMemoryTest, EveryBackendEncodingAndCrowdWritesTheReferenceIntoItsRange) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 1001, .influences = 4, .joint_count = 77, .normals = true, .seed = 3});
  auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  const uint64_t offset = 192;  // not at the start: the bytes before must stay untouched
  auto region =
      MakeRegion(dir, offset + 3 * wire::RegionFrameBytes(1001, 3, VertexEncoding::kFloat32, true));
  ASSERT_TRUE(t.client->RegisterRegion("frames", *region).ok());
  const RegionOutput output{.name = "frames", .region = region.get(), .offset = offset};
  int checked = 0;
  for (const auto& backend : backends->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    for (VertexEncoding encoding :
         {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
      for (uint32_t instances : {1u, 3u}) {
        for (bool normals : {false, true}) {
          const std::string what = backend.id() + " " + VertexEncodingName(encoding) + " x" +
                                   std::to_string(instances) + (normals ? " normals" : "");
          std::memset(region->bytes().data(), static_cast<int>(kCanary), region->byte_size());
          const auto palettes = CrowdPalettes(77, instances, checked);
          FrameResult result;
          Status s = t.client->Skin(info->mesh_id(), palettes, checked,
                                    {.backend = backend.id(),
                                     .want_normals = normals,
                                     .encoding = encoding,
                                     .instances = instances,
                                     .output = output},
                                    &result);
          ASSERT_TRUE(s.ok()) << what << ": " << s.ToString();
          EXPECT_EQ(result.frame, static_cast<uint64_t>(checked)) << what;
          EXPECT_TRUE(result.positions.empty()) << what << ": the vertices came over gRPC";
          ExpectRegionMatchesReference(*mesh, palettes, result, normals, SkinningMethod::kLinear,
                                       what);
          const auto layout = wire::LayoutInRegion(offset, 1001, instances, encoding, normals);
          // Only the frame's own ranges are written: not the gap before the normals either.
          ExpectUntouchedOutside(*region, offset, layout.end_offset, what);
          if (normals) {
            const uint64_t gap_begin = offset + layout.instance_bytes * instances;
            for (uint64_t i = gap_begin; i < layout.normals_offset; ++i) {
              ASSERT_EQ(region->bytes()[i], kCanary) << what << ": the gap before the normals";
            }
          }
          ++checked;
        }
      }
    }
  }
  EXPECT_GE(checked, 12 * 4) << "at least four backends ran";
  auto stats = t.client->GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->regions(), 1u);
  EXPECT_EQ(stats->region_frames(), static_cast<uint64_t>(checked));
  EXPECT_TRUE(t.client->UnregisterRegion("frames").ok());
}

TEST(SharedMemoryTest, StreamsWriteEachFrameInFlightIntoItsOwnSlotInEveryMethod) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 20'000, .influences = 4, .joint_count = 77, .normals = true, .seed = 8});
  auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const int window = 4;
  const uint64_t stride = wire::RegionFrameBytes(20'000, 2, VertexEncoding::kFloat32, true);
  auto region = MakeRegion(dir, window * stride);
  ASSERT_TRUE(t.client->RegisterRegion("stream", *region).ok());
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    const auto palettes = [&](uint64_t f) {
      if (method == SkinningMethod::kLinear) return CrowdPalettes(77, 2, f);
      auto a = MakeRigidPalette(77, 4, f), b = MakeRigidPalette(77, 5, f);
      a.insert(a.end(), b.begin(), b.end());
      return a;
    };
    uint64_t answered = 0;
    Status s = client::StreamFrames(
        *t.client,
        {.mesh_id = info->mesh_id(),
         .backend = method == SkinningMethod::kLinear ? "simd-openmp" : "sse-openmp",
         .want_normals = true,
         .method = method,
         .instances = 2,
         .output = {.name = "stream", .region = region.get(), .offset = 0, .stride = stride},
         .frames = 40,
         .window = window},
        palettes, [&](FrameResult& r, std::chrono::nanoseconds) {
          EXPECT_EQ(r.frame, answered);
          ExpectRegionMatchesReference(*mesh, palettes(r.frame), r, true, method,
                                       "frame " + std::to_string(r.frame));
          ++answered;
        });
    EXPECT_TRUE(s.ok()) << s.ToString();
    EXPECT_EQ(answered, 40u);
  }
}

// A frame on a stream that fails for its region is answered with its error; the next
// frame on the same stream, and the server, carry on.
Status SkinInto(TestServer& t, const std::string& mesh_id, const RegionOutput& output,
                uint64_t byte_size = 0) {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  request.set_backend("simd");
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  request.mutable_output()->set_region(output.name);
  request.mutable_output()->set_offset(output.offset);
  request.mutable_output()->set_byte_size(byte_size);
  grpc::ClientContext context;
  auto reader = t.client->stub().Skin(&context, request);
  v1::SkinResponse part;
  while (reader->Read(&part)) {
  }
  return wire::FromGrpc(reader->Finish());
}

void ExpectError(const Status& s, StatusCode code, std::initializer_list<std::string> words) {
  EXPECT_EQ(s.code(), code) << s.ToString();
  SCOPED_TRACE(s.ToString());
  for (const std::string& word : words) {
    EXPECT_NE(s.message().find(word), std::string::npos)
        << "'" << word << "' not in: " << s.message();
  }
}

TEST(SharedMemoryTest, HostileFramesGetAStatusNamingTheRegionAndTheLimit) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 1000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const uint64_t frame_bytes = wire::RegionFrameBytes(1000, 1, VertexEncoding::kFloat32, false);
  auto region = MakeRegion(dir, frame_bytes + 64);
  ASSERT_TRUE(t.client->RegisterRegion("small", *region).ok());
  const RegionOutput good{.name = "small", .region = region.get(), .offset = 64};

  EXPECT_TRUE(SkinInto(t, info->mesh_id(), good).ok());
  ExpectError(SkinInto(t, info->mesh_id(), {.name = "nobody", .region = region.get()}),
              StatusCode::kFailedPrecondition, {"nobody", "register"});
  ExpectError(SkinInto(t, info->mesh_id(), {.name = "small", .region = region.get(), .offset = 32}),
              StatusCode::kInvalidArgument, {"small", "offset = 32", "multiple of 64"});
  ExpectError(
      SkinInto(t, info->mesh_id(), {.name = "small", .region = region.get(), .offset = 128}),
      StatusCode::kInvalidArgument, {"small", std::to_string(frame_bytes + 64) + " bytes"});
  ExpectError(
      SkinInto(t, info->mesh_id(), {.name = "small", .region = region.get(), .offset = 1ull << 62}),
      StatusCode::kInvalidArgument, {"small"});
  const uint64_t payload =
      wire::LayoutInRegion(0, 1000, 1, VertexEncoding::kFloat32, false).bytes();
  ExpectError(SkinInto(t, info->mesh_id(), good, /*byte_size=*/payload - 4),
              StatusCode::kInvalidArgument, {"small", "output.byte_size"});

  // On one stream: good, bad, good; every frame answered in order.
  uint64_t answered = 0, failed = 0;
  const std::vector<RegionOutput> outputs = {good, {.name = "gone", .region = region.get()}, good};
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    FrameResult result;
    Status s = t.client->Skin(info->mesh_id(), MakeSyntheticPalette(77, 1, i), i,
                              {.backend = "simd", .output = outputs[i]}, &result);
    (s.ok() ? answered : failed) += 1;
  }
  EXPECT_EQ(answered, 2u);
  EXPECT_EQ(failed, 1u);
  EXPECT_TRUE(client::CheckHealth(t.client->channel(), std::chrono::seconds(5)).ok());
}

Status Register(client::SkinClient& c, const std::string& name, const std::string& key,
                uint64_t bytes) {
  v1::RegisterRegionRequest request;
  request.set_name(name);
  request.set_key(key);
  request.set_byte_size(bytes);
  grpc::ClientContext context;
  v1::RegionInfo info;
  return wire::FromGrpc(c.stub().RegisterRegion(&context, request, &info));
}

TEST(SharedMemoryTest, RegistrationIsCheckedAndBounded) {
  ShmDir dir;
  server::ServerOptions options = ShmOptions(dir);
  options.shm_budget_mb = 1;
  options.shm_max_regions = 3;
  options.shm_max_regions_per_connection = 2;
  TestServer t(options, Transport::kUnixSocket);
  auto region = MakeRegion(dir, 4096), second = MakeRegion(dir, 4096);
  const auto reg = [&](const std::string& name, const std::string& key, uint64_t bytes,
                       client::SkinClient* c = nullptr) {
    return Register(c != nullptr ? *c : *t.client, name, key, bytes);
  };
  ExpectError(reg("bad/name", region->key(), 4096), StatusCode::kInvalidArgument, {"bad/name"});
  ExpectError(reg("", region->key(), 4096), StatusCode::kInvalidArgument, {"region name"});
  ExpectError(reg("r", "../etc/passwd", 4096), StatusCode::kInvalidArgument, {"../etc/passwd"});
  ExpectError(reg("r", "..", 4096), StatusCode::kInvalidArgument, {"'..'"});
  ExpectError(reg("r", "missing", 4096), StatusCode::kInvalidArgument, {"missing", "--shm-dir"});
  ExpectError(reg("r", region->key(), 4097), StatusCode::kInvalidArgument,
              {"4096 bytes", "byte_size = 4097"});
  ExpectError(reg("r", region->key(), 0), StatusCode::kInvalidArgument, {"byte_size"});
  ASSERT_EQ(symlink(region->path().c_str(), (dir.path() + "/link").c_str()), 0);
  ExpectError(reg("r", "link", 4096), StatusCode::kInvalidArgument, {"symbolic link"});
  ASSERT_EQ(mkdir((dir.path() + "/adir").c_str(), 0700), 0);
  ExpectError(reg("r", "adir", 4096), StatusCode::kInvalidArgument, {"adir", "regular file"});
  ASSERT_EQ(mkfifo((dir.path() + "/afifo").c_str(), 0600), 0);
  ExpectError(reg("r", "afifo", 4096), StatusCode::kInvalidArgument, {"afifo", "regular file"});

  EXPECT_TRUE(reg("one", "/" + region->key(), 4096).ok()) << "a POSIX shm name's '/' is fine";
  ExpectError(reg("one", second->key(), 4096), StatusCode::kAlreadyExists, {"one"});
  // One registration per file: not under another name, nor through another connection.
  client::SkinClient other(client::MakeChannel(t.target, /*connection=*/1));
  ExpectError(reg("again", region->key(), 4096), StatusCode::kAlreadyExists,
              {"again", "registered already"});
  ExpectError(reg("again", region->key(), 4096, &other), StatusCode::kAlreadyExists,
              {"registered already"});
  auto big = MakeRegion(dir, 2 << 20);
  ExpectError(reg("big", big->key(), 2 << 20), StatusCode::kResourceExhausted,
              {"big", "--shm-budget-mb = 1"});
  EXPECT_TRUE(reg("two", second->key(), 4096).ok());
  // The cap is the client's (its process), whatever connection it uses.
  auto third = MakeRegion(dir, 4096);
  ExpectError(reg("three", third->key(), 4096), StatusCode::kResourceExhausted,
              {"--shm-max-regions-per-connection = 2"});
  ExpectError(reg("three", third->key(), 4096, &other), StatusCode::kResourceExhausted,
              {"--shm-max-regions-per-connection = 2"});
  auto list = other.ListRegions();  // the client's regions, on either connection
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->regions_size(), 2);
  EXPECT_EQ(list->mapped_bytes(), 2u * 4096);
  EXPECT_EQ(list->shm_dir(), dir.path());
  auto stats = t.client->GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->rejected_regions(), 3u);
  ExpectError(t.client->UnregisterRegion("nope"), StatusCode::kNotFound, {"nope"});
  EXPECT_TRUE(other.UnregisterRegion("one").ok());
  EXPECT_TRUE(t.client->UnregisterRegion("two").ok());
  EXPECT_EQ(t.client->ListRegions()->regions_size(), 0);
  EXPECT_TRUE(reg("again", region->key(), 4096).ok()) << "unregistered: the file is free again";
}

TEST(SharedMemoryTest, TheServerHoldsAtMostMaxRegions) {
  ShmDir dir;
  server::ServerOptions options = ShmOptions(dir);
  options.shm_max_regions = 2;
  TestServer t(options, Transport::kUnixSocket);
  std::vector<std::unique_ptr<SharedMemoryRegion>> regions;
  for (int i = 0; i < 3; ++i) regions.push_back(MakeRegion(dir, 4096));
  EXPECT_TRUE(Register(*t.client, "a", regions[0]->key(), 4096).ok());
  EXPECT_TRUE(Register(*t.client, "b", regions[1]->key(), 4096).ok());
  ExpectError(Register(*t.client, "c", regions[2]->key(), 4096), StatusCode::kResourceExhausted,
              {"'c'", "--shm-max-regions = 2"});
}

// A client's second connection is the same client: its names are the client's (another
// client's names are its own: tests/security/region_owners_test.cpp).
TEST(SharedMemoryTest, ANameIsOneRegionOfTheClientOnEveryConnection) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 500, .influences = 2});
  auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const uint64_t bytes = wire::RegionFrameBytes(500, 1, VertexEncoding::kFloat32, false);
  auto mine = MakeRegion(dir, bytes), theirs = MakeRegion(dir, bytes);
  client::SkinClient other(client::MakeChannel(t.target, /*connection=*/1));
  ASSERT_TRUE(t.client->RegisterRegion("avatar", *mine).ok());
  ExpectError(other.RegisterRegion("avatar", *theirs).status(), StatusCode::kAlreadyExists,
              {"avatar"});
  ASSERT_TRUE(other.RegisterRegion("avatar-2", *theirs).ok());
  const auto palette = MakeSyntheticPalette(77, 1, 5);
  FrameResult result;
  ASSERT_TRUE(t.client
                  ->Skin(info->mesh_id(), palette, 5,
                         {.backend = "simd", .output = {.name = "avatar", .region = mine.get()}},
                         &result)
                  .ok());
  ExpectRegionMatchesReference(*mesh, palette, result, false, SkinningMethod::kLinear, "mine");
  ExpectUntouchedOutside(*theirs, 0, 0, "the other connection's region");
}

TEST(SharedMemoryTest, UnregisterAnswersOnceTheFramesInFlightAreDoneAndNothingIsWrittenAfter) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 200'000, .influences = 4});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const int window = 8;
  const uint64_t stride = wire::RegionFrameBytes(200'000, 1, VertexEncoding::kFloat32, false);
  auto region = MakeRegion(dir, window * stride);
  ASSERT_TRUE(t.client->RegisterRegion("busy", *region).ok());
  std::atomic<bool> unregistered{false};
  std::atomic<uint64_t> failed{0}, answered{0};
  std::string failure;
  std::thread unregister([&] {
    while (answered.load() < 5) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_TRUE(t.client->UnregisterRegion("busy").ok());
    // The server may not write into the region any more: mark it and check later.
    std::memset(region->bytes().data(), static_cast<int>(kCanary), region->byte_size());
    unregistered.store(true);
  });
  const Status streamed = client::StreamFrames(
      *t.client,
      {.mesh_id = info->mesh_id(),
       .backend = "serial",  // slow frames: several in flight when the unregister comes
       .output = {.name = "busy", .region = region.get(), .stride = stride},
       .frames = 40,
       .window = window},
      [](uint64_t f) { return MakeSyntheticPalette(77, 1, f); },
      [&](FrameResult& r, std::chrono::nanoseconds) {
        ++answered;
        if (!r.status.ok()) {
          ++failed;
          if (failure.empty()) failure = r.status.ToString();
        }
      });
  unregister.join();
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(answered.load(), 40u);
  EXPECT_GT(failed.load(), 0u);
  EXPECT_NE(failure.find("busy"), std::string::npos) << failure;
  ExpectUntouchedOutside(*region, 0, 0, "after the unregister was answered");
  EXPECT_TRUE(client::CheckHealth(t.client->channel(), std::chrono::seconds(5)).ok());
}

TEST(SharedMemoryTest, AnUnusedRegionIsDroppedAfterTheIdleLimit) {
  ShmDir dir;
  server::ServerOptions options = ShmOptions(dir);
  options.shm_idle_seconds = 0.3;
  TestServer t(options, Transport::kUnixSocket);
  auto region = MakeRegion(dir, 4096);
  ASSERT_TRUE(t.client->RegisterRegion("idle", *region).ok());
  EXPECT_EQ(t.client->ListRegions()->regions_size(), 1);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (t.client->ListRegions()->regions_size() > 0 &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(t.client->ListRegions()->regions_size(), 0);
  EXPECT_EQ(t.client->GetServerStats()->region_bytes(), 0u);
}

TEST(SharedMemoryTest, ADeletedRegionFileKeepsWorkingAndATruncatedOneFailsItsFrames) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2000, .influences = 2});
  auto mesh = Mesh::Create(arrays).value();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const uint64_t bytes = wire::RegionFrameBytes(2000, 1, VertexEncoding::kFloat32, false);
  auto region = MakeRegion(dir, bytes);
  ASSERT_TRUE(t.client->RegisterRegion("r", *region).ok());
  const RegionOutput output{.name = "r", .region = region.get()};
  // Deleted: both mappings still share the pages.
  ASSERT_EQ(unlink(region->path().c_str()), 0);
  const auto palette = MakeSyntheticPalette(77, 1, 1);
  FrameResult result;
  ASSERT_TRUE(
      t.client->Skin(info->mesh_id(), palette, 1, {.backend = "simd", .output = output}, &result)
          .ok());
  ExpectRegionMatchesReference(*mesh, palette, result, false, SkinningMethod::kLinear, "deleted");
  // Truncated through another name for the same file: the next frame fails, naming it.
  auto other = MakeRegion(dir, bytes);
  ASSERT_TRUE(t.client->RegisterRegion("t", *other).ok());
  ASSERT_EQ(truncate(other->path().c_str(), 0), 0);
  Status s =
      t.client->Skin(info->mesh_id(), palette, 2,
                     {.backend = "simd", .output = {.name = "t", .region = other.get()}}, &result);
  ExpectError(s, StatusCode::kFailedPrecondition, {"'t'", "truncated"});
  EXPECT_TRUE(client::CheckHealth(t.client->channel(), std::chrono::seconds(5)).ok());
}

// A stream resolves its region once (RegionHandle) and does not fstat it per frame: a file
// truncated between two of its frames is caught by the SIGBUS guard on the next write, and
// every later frame fails naming the region, while the server goes on serving.
TEST(SharedMemoryTest, ARegionTruncatedBetweenAStreamsFramesFailsItsLaterFrames) {
  ShmDir dir;
  TestServer t(ShmOptions(dir), Transport::kUnixSocket);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 20'000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  const uint64_t bytes = wire::RegionFrameBytes(20'000, 1, VertexEncoding::kFloat32, false);
  auto region = MakeRegion(dir, bytes);
  ASSERT_TRUE(t.client->RegisterRegion("s", *region).ok());
  uint64_t answered = 0, failed_before = 0, failed_after = 0;
  std::string failure;
  const Status streamed = client::StreamFrames(
      *t.client,
      {.mesh_id = info->mesh_id(),
       .backend = "simd",
       .output = {.name = "s", .region = region.get(), .stride = bytes},
       .frames = 8,
       .window = 1},
      [](uint64_t f) { return MakeSyntheticPalette(77, 1, f); },
      [&](FrameResult& r, std::chrono::nanoseconds) {
        if (++answered <= 3) {
          failed_before += r.status.ok() ? 0 : 1;
          if (answered == 3) {
            EXPECT_EQ(truncate(region->path().c_str(), 0), 0);
          }
          return;
        }
        if (r.status.ok()) return;
        ++failed_after;
        if (failure.empty()) failure = r.status.ToString();
      });
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(answered, 8u);
  EXPECT_EQ(failed_before, 0u);
  EXPECT_EQ(failed_after, 5u) << "a frame after the truncation was answered as written";
  EXPECT_NE(failure.find("'s'"), std::string::npos) << failure;
  EXPECT_NE(failure.find("truncated"), std::string::npos) << failure;
  EXPECT_TRUE(client::CheckHealth(t.client->channel(), std::chrono::seconds(5)).ok());
}

TEST(SharedMemoryTest, ShmOffRefusesRegionsWithAClearStatus) {
  server::ServerOptions options;
  options.shm_dir = "";
  TestServer t(options);
  ExpectError(t.client->ListRegions().status(), StatusCode::kFailedPrecondition, {"--shm-dir"});
}

}  // namespace
}  // namespace skinserve::testing
