// FrameJob and its stream's plan (server/frames/frame_job.cpp, stream_plan.cpp) on an
// in-process engine, no gRPC server: the plan's key decides when a frame reuses it (only
// settings that fix the plan count; frame number, palette and morph weights do not); a
// reused plan answers right against the float64 reference; a mesh deleted under a cached
// plan fails the next frame NOT_FOUND and is not kept stored by the plan; the palette the
// engine reads is the request's parsed bytes, not a copy of them.
#include "frames/frame_job.h"

#include <grpcpp/impl/codegen/proto_utils.h>
#include <gtest/gtest.h>

#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>

#include "frames/stream_plan.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::testing {
namespace {

using server::FrameJob;
using server::StreamPlan;

constexpr uint32_t kJoints = 9;

// Waits for the engine's verdict on a job (OnFrameDone may run on a compute thread).
class DoneListener final : public FrameJob::Listener {
 public:
  void OnFrameDone(server::StreamAnswer*) override {
    std::lock_guard lock(mutex_);
    done_ = true;
    changed_.notify_all();
  }
  void OnPartsReady(server::StreamAnswer*) override {}
  void HoldForWire() override {}
  void ReleaseForWire() override {}
  void Wait() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return done_; });
    done_ = false;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool done_ = false;
};

class FrameJobTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto engine = Engine::Create({.compute_threads = 2, .enabled_backends = {"serial", "simd"}});
    ASSERT_TRUE(engine.ok()) << engine.status().ToString();
    engine_ = std::move(engine).value();
  }

  std::string AddMesh(uint32_t vertices, uint64_t seed) {
    const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                                 .influences = 2,
                                                 .joint_count = kJoints,
                                                 .normals = true,
                                                 .seed = seed});
    auto info = engine_->AddMesh(arrays);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    meshes_[info->id] = Mesh::Create(arrays).value();
    return info->id;
  }

  static v1::SkinRequest Request(const std::string& mesh_id, uint64_t frame) {
    v1::SkinRequest r;
    r.set_mesh_id(mesh_id);
    r.set_frame(frame);
    r.set_want_normals(true);
    r.set_palette(wire::EncodeFloats(MakeSyntheticPalette(kJoints, 7, frame)));
    return r;
  }

  // Prepares and skins `request` with `job` and `plan`; the answer, reassembled.
  client::FrameResult Skin(FrameJob& job, StreamPlan& plan, v1::SkinRequest& request) {
    client::FrameResult result;
    Status s = job.Prepare(request, *engine_, "simd", server::RegionCaller{}, &plan);
    if (s.ok()) s = engine_->Run(&job);
    if (!s.ok()) {
      job.Fail(s);
    } else {
      listener_.Wait();
    }
    client::FrameAssembler assembler;
    bool last = false;
    while (const grpc::ByteBuffer* bytes = job.NextPart(&last)) {
      grpc::ByteBuffer copy(*bytes);
      v1::SkinResponse part;
      EXPECT_TRUE(grpc::SerializationTraits<v1::SkinResponse>::Deserialize(&copy, &part).ok());
      job.PartWritten();
      if (assembler.Add(part, &result)) break;
    }
    job.DropWire();
    return result;
  }

  void ExpectReference(const client::FrameResult& r, const std::string& mesh_id, uint64_t frame) {
    ASSERT_TRUE(r.status.ok()) << r.status.ToString();
    const auto palette = MakeSyntheticPalette(kJoints, 7, frame);
    const Deviation d = CompareWithReference(*meshes_.at(mesh_id), palette, r.positions, r.normals);
    EXPECT_TRUE(d.within_tolerance())
        << "frame " << frame << ": position error " << d.max_position_error << " (tolerance "
        << d.position_tolerance << ")";
  }

  std::unique_ptr<Engine> engine_;
  std::map<std::string, std::shared_ptr<const Mesh>> meshes_;
  server::InflightBudget budget_{1ull << 30};
  DoneListener listener_;
};

TEST_F(FrameJobTest, ThePlansKeyIsTheSettingsThatFixItAndNothingElse) {
  const std::string a = AddMesh(500, 1), b = AddMesh(300, 2);
  StreamPlan plan;
  FrameJob job(&listener_, &budget_);
  v1::SkinRequest first = Request(a, 0);
  EXPECT_FALSE(plan.Matches(first, "simd")) << "an empty plan matches nothing";
  ASSERT_TRUE(plan.PlanFrame(first, "simd", *engine_, &job).ok());
  job.Fail(Internal("not skinned"));  // lets go of the pinned mesh
  EXPECT_TRUE(plan.Matches(first, "simd"));

  // What changes every frame keeps the plan.
  v1::SkinRequest same = Request(a, 99);
  same.add_morph_targets(0);
  same.add_morph_weights(0.5f);
  EXPECT_TRUE(plan.Matches(same, "simd")) << "frame, palette and morph weights are no key";
  same.mutable_output();  // an empty output message is still an output
  EXPECT_FALSE(plan.Matches(same, "simd"));

  // Each setting that fixes the plan, changed alone, does not match.
  const std::vector<std::pair<std::string, std::function<void(v1::SkinRequest&)>>> changes = {
      {"mesh_id", [&](v1::SkinRequest& r) { r.set_mesh_id(b); }},
      {"method", [](v1::SkinRequest& r) { r.set_method(v1::SKINNING_METHOD_DUAL_QUATERNION); }},
      {"encoding", [](v1::SkinRequest& r) { r.set_encoding(v1::ENCODING_FLOAT16); }},
      {"instances", [](v1::SkinRequest& r) { r.set_instances(2); }},
      {"want_normals", [](v1::SkinRequest& r) { r.set_want_normals(false); }},
      {"want_tangents", [](v1::SkinRequest& r) { r.set_want_tangents(true); }},
      {"pack_instances", [](v1::SkinRequest& r) { r.set_pack_instances(true); }},
      {"early_parts", [](v1::SkinRequest& r) { r.set_early_parts(true); }},
      {"output", [](v1::SkinRequest& r) { r.mutable_output()->set_region("r"); }},
  };
  for (const auto& [field, change] : changes) {
    v1::SkinRequest changed = Request(a, 1);
    change(changed);
    EXPECT_FALSE(plan.Matches(changed, "simd")) << field;
  }
  EXPECT_FALSE(plan.Matches(first, "serial")) << "backend";
  // instances 0 and 1 are the same batch.
  v1::SkinRequest one = Request(a, 2);
  one.set_instances(1);
  EXPECT_TRUE(plan.Matches(one, "simd"));
  plan.Reset();
  EXPECT_FALSE(plan.Matches(first, "simd")) << "a reset plan matches nothing";

  // Into a region: its name is a key, the offset is not (a double-buffering client changes
  // it every frame; each frame places itself).
  v1::SkinRequest in_region = Request(a, 3);
  in_region.mutable_output()->set_region("r");
  ASSERT_TRUE(plan.PlanFrame(in_region, "simd", *engine_, &job).ok());
  job.Fail(Internal("not skinned"));
  in_region.mutable_output()->set_offset(1 << 20);
  EXPECT_TRUE(plan.Matches(in_region, "simd")) << "output.offset is no key";
  in_region.mutable_output()->set_region("s");
  EXPECT_FALSE(plan.Matches(in_region, "simd")) << "output.region";
}

TEST_F(FrameJobTest, AStreamPlansOncePerSettingsAndAnswersTheReference) {
  const std::string a = AddMesh(700, 3), b = AddMesh(333, 4);
  StreamPlan plan;
  FrameJob job(&listener_, &budget_);
  const std::vector<std::string> meshes = {a, a, a, b, b, a};
  const std::vector<uint64_t> builds = {1, 1, 1, 2, 2, 3};
  for (uint64_t f = 0; f < meshes.size(); ++f) {
    v1::SkinRequest request = Request(meshes[f], f);
    ExpectReference(Skin(job, plan, request), meshes[f], f);
    EXPECT_EQ(plan.builds(), builds[f]) << "frame " << f;
  }
}

TEST_F(FrameJobTest, TheEngineReadsThePalettesParsedBytesInPlace) {
  const std::string a = AddMesh(256, 5);
  StreamPlan plan;
  FrameJob job(&listener_, &budget_);
  for (uint64_t f = 0; f < 3; ++f) {
    v1::SkinRequest request = Request(a, f);
    const auto* parsed = reinterpret_cast<const float*>(request.palette().data());
    ASSERT_TRUE(job.Prepare(request, *engine_, "simd", server::RegionCaller{}, &plan).ok());
    EXPECT_EQ(job.request.palette.data(), parsed) << "frame " << f << ": the palette was copied";
    EXPECT_EQ(job.request.palette.size(), 12u * kJoints);
    ASSERT_TRUE(engine_->Run(&job).ok());
    listener_.Wait();
    job.DropWire();
  }
}

TEST_F(FrameJobTest, AMeshDeletedUnderACachedPlanFailsTheNextFrameAndIsNotKept) {
  const std::string a = AddMesh(400, 6);
  StreamPlan plan;
  FrameJob job(&listener_, &budget_);
  for (uint64_t f = 0; f < 2; ++f) {
    v1::SkinRequest request = Request(a, f);
    ExpectReference(Skin(job, plan, request), a, f);
  }
  ASSERT_TRUE(engine_->DeleteMesh(a));
  EXPECT_EQ(engine_->Stats().meshes, 0u);
  EXPECT_EQ(engine_->GetMesh(a).status().code(), StatusCode::kNotFound)
      << "the cached plan kept the mesh stored";
  v1::SkinRequest request = Request(a, 2);
  const client::FrameResult r = Skin(job, plan, request);
  EXPECT_EQ(r.status.code(), StatusCode::kNotFound) << r.status.ToString();
  EXPECT_NE(r.status.message().find(a), std::string::npos) << r.status.ToString();
  EXPECT_FALSE(plan.Matches(request, "simd")) << "a failed plan is not kept";
  // Stored again (the same content, the same id): planned afresh.
  EXPECT_EQ(AddMesh(400, 6), a);
  request = Request(a, 3);
  ExpectReference(Skin(job, plan, request), a, 3);
}

// The mesh's entry outlives its deletion while another frame pins it: the cached plan can
// still reach it, and must see that it is no longer stored.
TEST_F(FrameJobTest, AMeshDeletedWhileAnotherFramePinsItFailsACachedPlansNextFrame) {
  const std::string a = AddMesh(400, 8);
  StreamPlan plan, other_plan;
  FrameJob job(&listener_, &budget_), other(&listener_, &budget_);
  v1::SkinRequest request = Request(a, 0);
  ExpectReference(Skin(job, plan, request), a, 0);
  v1::SkinRequest pinning = Request(a, 1);
  ASSERT_TRUE(other_plan.PlanFrame(pinning, "simd", *engine_, &other).ok());  // pins the mesh
  ASSERT_TRUE(engine_->DeleteMesh(a));
  request = Request(a, 2);
  const client::FrameResult r = Skin(job, plan, request);
  EXPECT_EQ(r.status.code(), StatusCode::kNotFound) << r.status.ToString();
  other.Fail(Internal("not skinned"));  // lets go of it
}

}  // namespace
}  // namespace skinserve::testing
