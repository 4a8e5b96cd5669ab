// A stream's frame plan (server/frames/stream_plan.h) through a real server over loopback
// (its Unix socket, for shared memory): a stream whose mesh, backend or region changes
// between frames is planned anew and answered right against the float64 reference; one
// that alternates between two places of a region keeps its plan, and each frame lands
// where it asked (a misaligned place is refused, writing nothing); a mesh
// deleted or a region unregistered between two frames of a cached plan fails the next
// frame with a status naming it, and nothing is written into the region after.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <span>

#include "skinserve/client/frame_stream.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using client::FrameResult;
using client::RegionOutput;
using client::SharedMemoryRegion;

constexpr std::byte kCanary{0x5A};
constexpr uint32_t kJoints = 77;  // MakeSyntheticMesh's default

class StreamPlanServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/dev/shm/skinserve-plan-XXXXXX";
    ASSERT_NE(mkdtemp(name), nullptr);
    dir_ = name;
    server::ServerOptions options;
    options.shm_dir = dir_;
    t_ = std::make_unique<TestServer>(options, Transport::kUnixSocket);
  }
  void TearDown() override {
    t_.reset();
    std::filesystem::remove_all(dir_);
  }

  // A mesh of `vertices`, uploaded; its arrays kept for the reference.
  std::string Upload(uint32_t vertices, uint64_t seed) {
    MeshArrays arrays = MakeSyntheticMesh(
        {.vertex_count = vertices, .influences = 2, .normals = true, .seed = seed});
    auto info = t_->client->Upload(arrays);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    meshes_[info->mesh_id()] = Mesh::Create(arrays).value();
    return info->mesh_id();
  }
  // A region of `bytes`, registered as `name`, filled with the canary.
  SharedMemoryRegion& Region(const std::string& name, uint64_t bytes) {
    auto region = SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("plan"), bytes, dir_);
    EXPECT_TRUE(region.ok()) << region.status().ToString();
    regions_[name] = std::move(region).value();
    Fill(name);
    EXPECT_TRUE(t_->client->RegisterRegion(name, *regions_[name]).ok());
    return *regions_[name];
  }
  void Fill(const std::string& name) {
    auto bytes = regions_.at(name)->bytes();
    std::memset(bytes.data(), static_cast<int>(kCanary), bytes.size());
  }
  // Whether the region (or its `bytes` from `offset`) still holds only the canary.
  bool Untouched(const std::string& name, uint64_t offset = 0,
                 uint64_t bytes = std::dynamic_extent) const {
    for (std::byte b : regions_.at(name)->bytes().subspan(offset, bytes)) {
      if (b != kCanary) return false;
    }
    return true;
  }

  // Sends one frame on `stream` and reads its answer.
  FrameResult Send(grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>& stream,
                   const std::string& mesh_id, const std::string& backend, uint64_t frame,
                   const std::string& region = "", uint64_t offset = 0) {
    v1::SkinRequest request;
    request.set_mesh_id(mesh_id);
    request.set_backend(backend);
    request.set_frame(frame);
    request.set_want_normals(true);
    request.set_palette(wire::EncodeFloats(MakeSyntheticPalette(kJoints, 5, frame)));
    RegionOutput output;
    if (!region.empty()) {
      output = {.name = region, .region = regions_.at(region).get(), .offset = offset};
      request.mutable_output()->set_region(region);
      request.mutable_output()->set_offset(offset);
    }
    EXPECT_TRUE(stream.Write(request));
    FrameResult result;
    client::FrameAssembler assembler(region.empty() ? nullptr : &output);
    v1::SkinResponse part;
    while (stream.Read(&part)) {
      if (assembler.Add(part, &result)) break;
    }
    return result;
  }

  // The frame's answer against the float64 reference of its mesh and palette.
  void ExpectReference(const FrameResult& r, const std::string& mesh_id, uint64_t frame,
                       const std::string& what) {
    ASSERT_TRUE(r.status.ok()) << what << ": " << r.status.ToString();
    const Mesh& mesh = *meshes_.at(mesh_id);
    ASSERT_EQ(r.vertices, mesh.vertex_count()) << what;
    const auto palette = MakeSyntheticPalette(kJoints, 5, frame);
    const std::span<const float> positions =
        r.in_region() ? r.region_floats(false, 0) : std::span<const float>(r.positions);
    const std::span<const float> normals =
        r.in_region() ? r.region_floats(true, 0) : std::span<const float>(r.normals);
    const Deviation d = CompareWithReference(mesh, palette, positions, normals);
    EXPECT_TRUE(d.within_tolerance()) << what << ": position error " << d.max_position_error
                                      << " (tolerance " << d.position_tolerance << ")";
  }

  std::string dir_;
  std::unique_ptr<TestServer> t_;
  std::map<std::string, std::shared_ptr<const Mesh>> meshes_;
  std::map<std::string, std::unique_ptr<SharedMemoryRegion>> regions_;
};

TEST_F(StreamPlanServiceTest, AStreamWhoseMeshBackendOrRegionChangesIsPlannedAnew) {
  const std::string a = Upload(3001, 1), b = Upload(1203, 2);
  Region("r1", wire::RegionFrameBytes(3001, 1, VertexEncoding::kFloat32, true));
  Region("r2", wire::RegionFrameBytes(3001, 1, VertexEncoding::kFloat32, true));
  grpc::ClientContext context;
  auto stream = t_->client->stub().StreamSkin(&context);
  struct Step {
    std::string mesh, backend, region;
  };
  // Each setting changes alone, then back; a few frames repeat the one before (reused).
  const std::vector<Step> steps = {{a, "simd", ""},     {a, "simd", ""},   {b, "simd", ""},
                                   {b, "simd", ""},     {a, "simd", ""},   {a, "serial", ""},
                                   {a, "serial", ""},   {a, "simd", ""},   {a, "simd", "r1"},
                                   {a, "simd", "r1"},   {a, "simd", "r2"}, {b, "simd", "r2"},
                                   {b, "serial", "r2"}, {a, "simd", "r1"}, {a, "simd", ""}};
  for (std::size_t f = 0; f < steps.size(); ++f) {
    const Step& s = steps[f];
    const std::string what = "frame " + std::to_string(f) + " (" + s.backend + ", mesh " +
                             (s.mesh == a ? "a" : "b") + ", region '" + s.region + "')";
    const FrameResult r = Send(*stream, s.mesh, s.backend, f, s.region);
    EXPECT_EQ(r.in_region(), !s.region.empty()) << what;
    ExpectReference(r, s.mesh, f, what);
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST_F(StreamPlanServiceTest, AMeshDeletedBetweenFramesFailsTheNextAndWritesNothing) {
  const std::string a = Upload(2048, 3);
  Region("r", wire::RegionFrameBytes(2048, 1, VertexEncoding::kFloat32, true));
  grpc::ClientContext context;
  auto stream = t_->client->stub().StreamSkin(&context);
  for (uint64_t f = 0; f < 3; ++f)
    ExpectReference(Send(*stream, a, "simd", f, "r"), a, f, "before");
  ASSERT_TRUE(t_->client->DeleteMesh(a).value());
  Fill("r");
  for (uint64_t f = 3; f < 5; ++f) {  // the plan is cached: its mesh must be looked at again
    const FrameResult r = Send(*stream, a, "simd", f, "r");
    EXPECT_EQ(r.status.code(), StatusCode::kNotFound) << r.status.ToString();
    EXPECT_NE(r.status.message().find(a), std::string::npos) << r.status.ToString();
    EXPECT_TRUE(Untouched("r")) << "frame " << f << " wrote into the region after the delete";
  }
  // Uploaded again: the same stream is planned anew and answered.
  EXPECT_EQ(Upload(2048, 3), a);
  ExpectReference(Send(*stream, a, "simd", 5, "r"), a, 5, "after the upload");
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST_F(StreamPlanServiceTest, ARegionUnregisteredBetweenFramesFailsTheNextAndWritesNothing) {
  const std::string a = Upload(2048, 4);
  const uint64_t bytes = wire::RegionFrameBytes(2048, 1, VertexEncoding::kFloat32, true);
  Region("r", bytes);
  grpc::ClientContext context;
  auto stream = t_->client->stub().StreamSkin(&context);
  for (uint64_t f = 0; f < 3; ++f)
    ExpectReference(Send(*stream, a, "simd", f, "r"), a, f, "before");
  ASSERT_TRUE(t_->client->UnregisterRegion("r").ok());
  Fill("r");  // this process's mapping stays: any write the server made would show here
  for (uint64_t f = 3; f < 5; ++f) {
    const FrameResult r = Send(*stream, a, "simd", f, "r");
    EXPECT_FALSE(r.status.ok()) << "frame " << f << " was answered into an unregistered region";
    EXPECT_NE(r.status.message().find("'r'"), std::string::npos) << r.status.ToString();
    EXPECT_TRUE(Untouched("r")) << "frame " << f << " wrote into the unregistered region";
  }
  // The stream goes on: without the region, and into the region registered again.
  ExpectReference(Send(*stream, a, "simd", 5), a, 5, "over gRPC");
  ASSERT_TRUE(t_->client->RegisterRegion("r", *regions_.at("r")).ok());
  ExpectReference(Send(*stream, a, "simd", 6, "r"), a, 6, "registered again");
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

// A client double-buffering a region alternates its frames' offsets: the offset is no part
// of the plan's key, so the stream keeps its plan (the engine's counters say so), and each
// frame is written at its own offset and nowhere else.
TEST_F(StreamPlanServiceTest, AStreamAlternatingPlacesInARegionKeepsItsPlan) {
  const std::string a = Upload(3001, 5);
  const uint64_t slot = wire::RoundUpToRegionAlignment(
      wire::RegionFrameBytes(3001, 1, VertexEncoding::kFloat32, true));
  SharedMemoryRegion& region = Region("r", 2 * slot);
  grpc::ClientContext context;
  auto stream = t_->client->stub().StreamSkin(&context);
  const auto before = t_->client->GetServerStats();
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  constexpr uint64_t kFrames = 6;
  for (uint64_t f = 0; f < kFrames; ++f) {
    const uint64_t offset = (f % 2) * slot;
    Fill("r");
    const FrameResult r = Send(*stream, a, "simd", f, "r", offset);
    const std::string what = "frame " + std::to_string(f) + " at offset " + std::to_string(offset);
    ExpectReference(r, a, f, what);
    ASSERT_TRUE(r.in_region()) << what;
    EXPECT_EQ(r.region_positions.data(), region.bytes().data() + offset) << what;
    EXPECT_TRUE(Untouched("r", offset == 0 ? slot : 0, slot))
        << what << " wrote into the other slot";
  }
  const auto after = t_->client->GetServerStats();
  ASSERT_TRUE(after.ok()) << after.status().ToString();
  EXPECT_EQ(after->frame_plans_built() - before->frame_plans_built(), 1u)
      << "the plan was rebuilt when only the offset changed";
  EXPECT_EQ(after->frame_plans_reused() - before->frame_plans_reused(), kFrames - 1);

  // A misaligned offset on the kept plan: refused naming the field, nothing written, and
  // the stream goes on.
  Fill("r");
  const FrameResult bad = Send(*stream, a, "simd", kFrames, "r", slot + 4);
  EXPECT_EQ(bad.status.code(), StatusCode::kInvalidArgument) << bad.status.ToString();
  EXPECT_NE(bad.status.message().find("output.offset"), std::string::npos) << bad.status.ToString();
  EXPECT_TRUE(Untouched("r")) << "the misaligned frame wrote into the region";
  ExpectReference(Send(*stream, a, "simd", kFrames + 1, "r", slot), a, kFrames + 1, "after it");
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

}  // namespace
}  // namespace skinserve::testing
