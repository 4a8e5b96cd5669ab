// The engine's contract: errors by code and message, results against the reference,
// bounded queues, dedupe, shutdown.
#include "skinserve/engine/engine.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <future>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>

#include "cpu_backend_ids.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve {
namespace {

std::unique_ptr<Engine> MakeEngine(EngineOptions options = {}) {
  if (options.enabled_backends.empty()) options.enabled_backends = {"serial", "passthrough"};
  auto engine = Engine::Create(options);
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  return std::move(engine).value();
}

struct Frame {
  std::vector<float> palette;
  std::vector<float> positions;
  std::vector<float> normals;
  SkinRequest Request(const MeshInfo& mesh, const std::string& backend, uint64_t frame,
                      bool with_normals = false) {
    palette = MakeSyntheticPalette(mesh.joint_count, 11, frame);
    positions.assign(3ull * mesh.vertex_count, 0.0f);
    normals.assign(with_normals ? 3ull * mesh.vertex_count : 0, 0.0f);
    return {mesh.id, backend, palette, 1, positions, normals};
  }
};

TEST(EngineTest, SkinsAgainstTheReference) {
  auto engine = MakeEngine();
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 777, .influences = 3, .normals = true});
  auto info = engine->AddMesh(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  Frame frame;
  SkinRequest request = frame.Request(*info, "serial", 5, /*with_normals=*/true);
  const std::vector<float> palette = frame.palette;
  FrameTiming timing;
  ASSERT_TRUE(engine->SkinBlocking(std::move(request), &timing).ok());
  auto mesh = Mesh::Create(arrays).value();
  const Deviation d = CompareWithReference(*mesh, palette, frame.positions, frame.normals);
  EXPECT_TRUE(d.within_tolerance()) << d.max_position_error << " " << d.max_normal_error;
  EXPECT_GT(timing.compute_ns, 0);
  const EngineStats stats = engine->Stats();
  EXPECT_EQ(stats.backends[0].id, "serial");
  EXPECT_EQ(stats.backends[0].frames, 1u);
  EXPECT_EQ(stats.backends[0].vertices, 777u);
}

// Tangents through the engine: a crowd of 3 instances, each with its own palette, the same
// morph weights (tangent deltas included), on every backend that runs here (the OpenCL ones
// where a platform is installed) in each method it lists; each instance's positions,
// normals and tangents against the float64 reference (CompareWithReference: 1e-5 relative
// to the frame's scale, normals and tangents' xyz 1e-5, tangents' w exact).
TEST(EngineTest, CrowdTangentsMatchTheReferenceOnEveryBackend) {
  auto engine = MakeEngine(
      {.compute_threads = 2, .enabled_backends = {"serial", "opencl", "opencl-zerocopy"}});
  MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 1001, .influences = 3, .normals = true, .tangents = true, .seed = 21});
  AddSyntheticMorphTargets({.targets = 6, .fraction = 0.3, .seed = 21}, &arrays);
  auto info = engine->AddMesh(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays).value();
  ASSERT_TRUE(mesh->has_morph_tangents());
  constexpr uint32_t kInstances = 3;
  const std::vector<MorphWeight> weights = MakeMorphWeights(6, 3, 21, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::size_t floats = 12ull * mesh->joint_count(), n = mesh->vertex_count();
  int skinned = 0;
  for (const BackendInfo& backend : engine->Backends()) {
    if (!backend.available) continue;
    for (SkinningMethod method : backend.methods) {
      SCOPED_TRACE(fmt::format("{} {}", backend.id, MethodName(method)));
      std::vector<float> palettes;
      for (uint32_t k = 0; k < kInstances; ++k) {
        const auto one = method == SkinningMethod::kDualQuaternion
                             ? MakeRigidPalette(mesh->joint_count(), 21, k)
                             : MakeSyntheticPalette(mesh->joint_count(), 21, k);
        palettes.insert(palettes.end(), one.begin(), one.end());
      }
      std::vector<float> positions(3 * n * kInstances, nan), normals(3 * n * kInstances, nan),
          tangents(4 * n * kInstances, nan);
      SkinRequest request{.mesh_id = info->id,
                          .backend = backend.id,
                          .palette = palettes,
                          .instances = kInstances,
                          .positions = positions,
                          .normals = normals,
                          .tangents = tangents,
                          .method = method,
                          .morph_weights = weights};
      ASSERT_TRUE(engine->SkinBlocking(std::move(request)).ok());
      const std::span<const float> all_palettes(palettes), p(positions), nn(normals), t(tangents);
      for (uint32_t k = 0; k < kInstances; ++k) {
        const Deviation d = CompareWithReference(
            *mesh, all_palettes.subspan(k * floats, floats), p.subspan(3 * n * k, 3 * n),
            nn.subspan(3 * n * k, 3 * n), method, weights, t.subspan(4 * n * k, 4 * n));
        EXPECT_TRUE(d.within_tolerance())
            << "instance " << k << ": position error " << d.max_position_error << " ("
            << d.position_tolerance << "), normal error " << d.max_normal_error << " ("
            << d.normal_tolerance << "), tangent error " << d.max_tangent_error << " ("
            << d.tangent_tolerance << ")";
      }
      ++skinned;
    }
  }
  EXPECT_GE(skinned, 2);  // serial, in both methods, wherever this runs
}

// A job that checks, in OnInstanceSkinned, that the output it is handed holds the instance
// it is told of, skinned (against the float64 reference), and can fail one instance on
// purpose. `scratch`: skinned into the compute thread's scratch instead of the request's
// arrays (SkinRequest::skin_into_scratch).
class InstanceHookJob final : public SkinJob {
 public:
  InstanceHookJob(const Mesh& mesh, std::vector<float> palettes, uint32_t instances, bool scratch)
      : seen(instances), mesh_(mesh), palettes_(std::move(palettes)) {
    request.palette = palettes_;
    request.instances = instances;
    request.skin_into_scratch = scratch;
    request.scratch_normals = scratch;
    if (!scratch) {
      positions_.assign(3ull * mesh.vertex_count() * instances, 0.0f);
      normals_.assign(positions_.size(), 0.0f);
      request.positions = positions_;
      request.normals = normals_;
    }
  }
  std::optional<uint32_t> fail_instance;
  std::promise<Status> done;
  std::vector<std::atomic<int>> seen;  // hook calls per instance
  std::atomic<int> skinned_before_hook{0};
  std::atomic<bool> hook_on_caller_thread{false};
  std::thread::id caller = std::this_thread::get_id();
  int hooks_at_done = -1;

 private:
  Status OnInstanceSkinned(uint32_t instance, std::span<const float> positions,
                           std::span<const float> normals) override {
    seen[instance].fetch_add(1);
    if (std::this_thread::get_id() == caller) hook_on_caller_thread = true;
    const std::size_t values = 3ull * mesh_.vertex_count();
    const std::size_t floats = 12ull * mesh_.joint_count();
    const bool where = request.skin_into_scratch
                           ? positions.data() != nullptr
                           : positions.data() == positions_.data() + instance * values &&
                                 normals.data() == normals_.data() + instance * values;
    const Deviation d = CompareWithReference(
        mesh_, std::span<const float>(palettes_).subspan(instance * floats, floats), positions,
        normals);
    if (where && positions.size() == values && normals.size() == values && d.within_tolerance()) {
      skinned_before_hook.fetch_add(1);
    }
    if (fail_instance == instance) return Internal("instance 3's encoding failed");
    return Status::Ok();
  }
  void OnSkinned(Status status, const FrameTiming&) override {
    hooks_at_done = 0;
    for (auto& n : seen) hooks_at_done += n.load();
    done.set_value(std::move(status));
  }
  const Mesh& mesh_;
  std::vector<float> palettes_;
  std::vector<float> positions_, normals_;
};

TEST(EngineTest, OnInstanceSkinnedRunsOncePerSkinnedInstanceBeforeOnSkinned) {
  auto engine = MakeEngine(
      {.compute_threads = 2, .enabled_backends = {"serial", kSimdOpenMpTestBackend, "opencl"}});
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 3000, .influences = 2, .normals = true});
  auto info = engine->AddMesh(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays).value();
  constexpr uint32_t kInstances = 6;
  std::vector<float> palettes;
  for (uint32_t k = 0; k < kInstances; ++k) {
    const auto one = MakeSyntheticPalette(info->joint_count, 13, k);
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  std::vector<std::string> backends;  // OpenCL where a platform is installed (not under qemu)
  for (const BackendInfo& b : engine->Backends()) {
    if (b.available) backends.push_back(b.id);
  }
  ASSERT_GE(backends.size(), 2u);
  for (const bool scratch : {false, true}) {
    for (const std::string& backend : backends) {
      for (const bool fail : {false, true}) {
        SCOPED_TRACE(fmt::format("{}, {}, {}", scratch ? "thread scratch" : "request arrays",
                                 backend,
                                 fail ? "instance 3's hook fails" : "every hook succeeds"));
        InstanceHookJob job(*mesh, palettes, kInstances, scratch);
        job.request.mesh_id = info->id;
        job.request.backend = backend;
        if (fail) job.fail_instance = 3;
        std::future<Status> result = job.done.get_future();
        ASSERT_TRUE(engine->Submit(&job).ok());
        const Status status = result.get();
        if (fail) {
          EXPECT_EQ(status.code(), StatusCode::kInternal);
          EXPECT_NE(status.message().find("instance 3"), std::string::npos) << status.ToString();
        } else {
          EXPECT_TRUE(status.ok()) << status.ToString();
        }
        for (uint32_t k = 0; k < kInstances; ++k) {
          EXPECT_EQ(job.seen[k].load(), 1) << "instance " << k;
        }
        EXPECT_EQ(job.hooks_at_done, static_cast<int>(kInstances));
        EXPECT_EQ(job.skinned_before_hook.load(), static_cast<int>(kInstances));
        EXPECT_FALSE(job.hook_on_caller_thread.load());
      }
    }
  }
}

// Scratch output is for jobs that take each instance as it is skinned, and bounded.
TEST(EngineTest, ScratchOutputIsRefusedWhereItCannotWork) {
  auto engine = MakeEngine();
  auto small = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 10})).value();
  Frame frame;
  SkinRequest request = frame.Request(small, "serial", 0);
  request.skin_into_scratch = true;
  Status s = engine->Submit(request, [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("needs a SkinJob"), std::string::npos) << s.message();

  const MeshArrays big_arrays = MakeSyntheticMesh({.vertex_count = 200000, .normals = true});
  auto big = engine->AddMesh(big_arrays).value();
  auto big_mesh = Mesh::Create(big_arrays).value();
  const auto palette = MakeSyntheticPalette(big.joint_count, 3, 0);
  InstanceHookJob with_arrays(*big_mesh, palette, 1, false);
  with_arrays.request.mesh_id = big.id;
  with_arrays.request.backend = "serial";
  with_arrays.request.skin_into_scratch = true;  // and arrays too
  s = engine->Submit(&with_arrays);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("positions and normals must be empty"), std::string::npos)
      << s.message();
  // 200k vertices with normals: 1.2M floats, over the 1M floats a thread keeps.
  InstanceHookJob too_big(*big_mesh, palette, 1, true);
  too_big.request.mesh_id = big.id;
  too_big.request.backend = "serial";
  s = engine->Submit(&too_big);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("over the limit of 1048576"), std::string::npos) << s.message();
}

// A job planned by Engine::Plan: the mesh is looked up and pinned once, so a frame planned
// before its mesh is deleted is still skinned; what the plan checks fails before any
// buffer is sized, naming it; a dropped plan unpins the mesh.
class PlannedJob final : public SkinJob {
 public:
  void Drop() { DropPlan(); }
  std::promise<Status> done;
  FrameTiming timing;  // the last OnSkinned's

 private:
  void OnSkinned(Status status, const FrameTiming& t) override {
    timing = t;
    done.set_value(status);
  }
};

TEST(EngineTest, APlannedFrameUsesItsPinnedMeshAndPlansFailNamingWhy) {
  auto engine = MakeEngine();
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 500, .influences = 2});
  auto info = engine->AddMesh(arrays);
  ASSERT_TRUE(info.ok());
  PlannedJob job;
  job.request.mesh_id = info->id;
  job.request.backend = "serial";
  ASSERT_TRUE(engine->Plan(&job).ok());
  EXPECT_TRUE(job.plan().planned);
  EXPECT_EQ(job.plan().vertex_count, 500u);
  EXPECT_EQ(job.plan().joint_count, info->joint_count);
  EXPECT_FALSE(job.plan().has_normals);
  // Deleted after planning: the plan's pin keeps it for this frame.
  EXPECT_TRUE(engine->DeleteMesh(info->id));
  const auto palette = MakeSyntheticPalette(info->joint_count, 3, 1);
  std::vector<float> positions(3 * 500);
  job.request.palette = palette;
  job.request.positions = positions;
  auto done = job.done.get_future();
  ASSERT_TRUE(engine->Submit(&job).ok());
  ASSERT_TRUE(done.get().ok());
  auto mesh = Mesh::Create(arrays).value();
  EXPECT_TRUE(CompareWithReference(*mesh, palette, positions, {}).within_tolerance());
  EXPECT_FALSE(job.plan().planned) << "done: the plan is gone with the frame";

  auto again = engine->AddMesh(arrays);
  ASSERT_TRUE(again.ok());
  PlannedJob bad;
  bad.request.mesh_id = again->id;
  bad.request.backend = "no-such";
  EXPECT_NE(engine->Plan(&bad).message().find("no-such"), std::string::npos);
  bad.request.backend = "passthrough";  // linear only
  bad.request.method = SkinningMethod::kDualQuaternion;
  EXPECT_EQ(engine->Plan(&bad).code(), StatusCode::kInvalidArgument);
  bad.request.method = SkinningMethod::kLinear;
  bad.request.backend = "serial";
  bad.request.mesh_id = "unknown";
  EXPECT_EQ(engine->Plan(&bad).code(), StatusCode::kNotFound);
  bad.request.mesh_id = again->id;
  bad.request.instances = 65;
  EXPECT_NE(engine->Plan(&bad).message().find("instances = 65"), std::string::npos);
  EXPECT_FALSE(bad.plan().planned);
  bad.request.instances = 1;
  ASSERT_TRUE(engine->Plan(&bad).ok());
  bad.Drop();
  EXPECT_FALSE(bad.plan().planned);
  EXPECT_TRUE(engine->DeleteMesh(again->id));
  EXPECT_EQ(engine->Plan(&bad).code(), StatusCode::kNotFound) << "unpinned and deleted";
}

TEST(EngineTest, DedupesMeshesByContent) {
  auto engine = MakeEngine();
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 10});
  auto first = engine->AddMesh(arrays);
  auto second = engine->AddMesh(arrays);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_EQ(first->id, second->id);
  EXPECT_FALSE(first->already_stored);
  EXPECT_TRUE(second->already_stored);
  EXPECT_EQ(engine->Stats().meshes, 1u);
  EXPECT_TRUE(engine->DeleteMesh(first->id));
  EXPECT_EQ(engine->GetMesh(first->id).status().code(), StatusCode::kNotFound);
}

TEST(EngineTest, NamesWhatIsWrongWithARequest) {
  auto engine = MakeEngine();
  auto info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 10})).value();
  Frame frame;

  SkinRequest unknown_mesh = frame.Request(info, "serial", 0);
  unknown_mesh.mesh_id = "feed";
  Status s = engine->Submit(unknown_mesh, [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_NE(s.message().find("upload it again"), std::string::npos) << s.message();

  s = engine->Submit(frame.Request(info, "warp-drive", 0), [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("available backends: serial, passthrough"), std::string::npos)
      << s.message();

  s = engine->Submit(frame.Request(info, "sse", 0), [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << "not enabled in this engine";

  SkinRequest short_palette = frame.Request(info, "serial", 0);
  short_palette.palette = short_palette.palette.first(short_palette.palette.size() - 1);
  s = engine->Submit(short_palette, [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("expected 12 * joint_count = 924"), std::string::npos) << s.message();

  SkinRequest nan_palette = frame.Request(info, "serial", 0);
  frame.palette[12 * 3 + 6] = std::numeric_limits<float>::quiet_NaN();
  s = engine->Submit(nan_palette, [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("palette[joint 3][row 1, col 2]"), std::string::npos) << s.message();

  SkinRequest normals_without = frame.Request(info, "serial", 0, /*with_normals=*/true);
  s = engine->Submit(normals_without, [](Status, FrameTiming) { FAIL(); });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("mesh has none"), std::string::npos) << s.message();
}

// snorm16 written by `simd` for a crowd, with the caller's box_scratch: the engine hands
// each instance its own 3 * V floats of it (each holds that instance's skinned positions,
// within the float64 reference's tolerance), and a box_scratch of any other size is
// refused naming it.
TEST(EngineTest, ACrowdsBoxScratchIsSplitPerInstanceAndItsSizeChecked) {
  auto engine = MakeEngine({.enabled_backends = {"simd"}});
  auto arrays = MakeSyntheticMesh({.vertex_count = 3001, .influences = 4});
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok());
  auto info = engine->AddMesh(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  constexpr uint32_t kInstances = 3;
  const std::size_t n = info->vertex_count;
  std::vector<float> palettes;
  for (uint32_t k = 0; k < kInstances; ++k) {
    const auto one = MakeSyntheticPalette(info->joint_count, 5, k);
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  const std::size_t bytes = EncodedBytes(VertexEncoding::kSnorm16, n);
  std::vector<std::byte> encoded(bytes * kInstances);
  std::vector<Bounds> boxes(kInstances);
  std::vector<float> scratch(3 * n * kInstances, std::numeric_limits<float>::quiet_NaN());
  const auto request = [&](std::span<float> box_scratch) {
    return SkinRequest{.mesh_id = info->id,
                       .backend = "simd",
                       .palette = palettes,
                       .instances = kInstances,
                       .encoded = {.encoding = VertexEncoding::kSnorm16,
                                   .positions = encoded,
                                   .bounds = boxes.data(),
                                   .box_scratch = box_scratch}};
  };
  const Status skinned = engine->SkinBlocking(request(scratch));
  ASSERT_TRUE(skinned.ok()) << skinned.ToString();
  const std::size_t floats = 12ull * info->joint_count;
  for (uint32_t k = 0; k < kInstances; ++k) {
    const Deviation d =
        CompareWithReference(**mesh, std::span<const float>(palettes).subspan(k * floats, floats),
                             std::span<const float>(scratch).subspan(3 * n * k, 3 * n), {});
    EXPECT_TRUE(d.within_tolerance())
        << "instance " << k << "'s box_scratch: position error " << d.max_position_error;
  }
  const Status refused =
      engine->SkinBlocking(request(std::span<float>(scratch).first(scratch.size() - 3)));
  EXPECT_EQ(refused.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("box_scratch holds 27006 floats; 3 instances of 3001 "
                                   "vertices need 27009"),
            std::string::npos)
      << refused.message();
}

TEST(EngineTest, RejectsUnknownEnabledBackend) {
  auto engine = Engine::Create({.enabled_backends = {"serial", "quantum"}});
  ASSERT_FALSE(engine.ok());
  EXPECT_NE(engine.status().message().find("'quantum'"), std::string::npos);
}

TEST(EngineTest, AFullQueueSaysResourceExhausted) {
  auto engine = MakeEngine({.compute_threads = 1, .queue_capacity = 2});
  auto info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 100})).value();
  Frame frames[4];
  // The first frame's completion holds the only compute thread until we let it go.
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> first_done;
  ASSERT_TRUE(engine
                  ->Submit(frames[0].Request(info, "serial", 0),
                           [&](Status, FrameTiming) {
                             first_done.set_value();
                             released.wait();
                           })
                  .ok());
  first_done.get_future().wait();
  std::atomic<int> answered{0};
  auto count = [&](Status status, FrameTiming) {
    EXPECT_TRUE(status.ok());
    answered.fetch_add(1);
  };
  EXPECT_TRUE(engine->Submit(frames[1].Request(info, "serial", 1), count).ok());
  EXPECT_TRUE(engine->Submit(frames[2].Request(info, "serial", 2), count).ok());
  Status full = engine->Submit(frames[3].Request(info, "serial", 3), count);
  EXPECT_EQ(full.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(full.message().find("queue is full"), std::string::npos) << full.message();
  release.set_value();
  engine->Shutdown();
  EXPECT_EQ(answered.load(), 2);
  EXPECT_EQ(engine->Stats().rejected_queue_full, 1u);
}

// A group (a tick's characters) takes one place in the queue whatever its size; each job
// gets its own verdict, a refused one is never called back, and every accepted one is
// skinned right, crowds included.
TEST(EngineTest, AGroupTakesOneQueuePlaceAndEachJobItsOwnVerdict) {
  auto engine = MakeEngine({.compute_threads = 2, .queue_capacity = 1});
  const MeshArrays small = MakeSyntheticMesh({.vertex_count = 300, .influences = 2, .seed = 3});
  const MeshArrays other = MakeSyntheticMesh({.vertex_count = 200, .influences = 4, .seed = 4});
  const MeshInfo a = engine->AddMesh(small).value();
  const MeshInfo b = engine->AddMesh(other).value();
  constexpr int kJobs = 12;
  std::vector<PlannedJob> jobs(kJobs);
  std::vector<std::vector<float>> palettes(kJobs), outputs(kJobs);
  SkinGroup group;
  for (int i = 0; i < kJobs; ++i) {
    const MeshInfo& info = i % 2 == 0 ? a : b;
    const uint32_t instances = i % 3 == 0 ? 2 : 1;  // a crowd now and then
    for (uint32_t k = 0; k < instances; ++k) {
      const auto one = MakeSyntheticPalette(info.joint_count, 7 + i, k);
      palettes[i].insert(palettes[i].end(), one.begin(), one.end());
    }
    outputs[i].assign(3ull * info.vertex_count * instances, 0.0f);
    jobs[i].request.mesh_id = info.id;
    jobs[i].request.backend = "serial";
    jobs[i].request.instances = instances;
    jobs[i].request.palette = palettes[i];
    jobs[i].request.positions = outputs[i];
    group.jobs.push_back(&jobs[i]);
  }
  jobs[5].request.palette = std::span<const float>(palettes[5]).first(12);  // short
  jobs[8].request.mesh_id = "no-such-mesh";
  std::vector<Status> verdicts(kJobs);
  std::vector<std::future<Status>> done;
  for (auto& job : jobs) done.push_back(job.done.get_future());
  engine->SubmitGroup(&group, verdicts);
  for (int i = 0; i < kJobs; ++i) {
    if (i == 5) {
      EXPECT_EQ(verdicts[i].code(), StatusCode::kInvalidArgument) << verdicts[i].ToString();
    } else if (i == 8) {
      EXPECT_EQ(verdicts[i].code(), StatusCode::kNotFound) << verdicts[i].ToString();
    } else {
      ASSERT_TRUE(verdicts[i].ok()) << i << ": " << verdicts[i].ToString();
    }
  }
  for (int i = 0; i < kJobs; ++i) {
    if (i == 5 || i == 8) {
      EXPECT_EQ(done[i].wait_for(std::chrono::milliseconds(0)), std::future_status::timeout)
          << "a refused job was called back";
      continue;
    }
    ASSERT_TRUE(done[i].get().ok()) << i;
    const MeshArrays& arrays = i % 2 == 0 ? small : other;
    auto mesh = Mesh::Create(arrays).value();
    const std::size_t floats = 12ull * mesh->joint_count();
    const std::size_t values = 3ull * mesh->vertex_count();
    for (uint32_t k = 0; k < jobs[i].request.instances; ++k) {
      const Deviation d = CompareWithReference(
          *mesh, std::span<const float>(palettes[i]).subspan(k * floats, floats),
          std::span<const float>(outputs[i]).subspan(k * values, values), {});
      EXPECT_TRUE(d.within_tolerance()) << "job " << i << " instance " << k;
    }
  }
  engine->Shutdown();
  EXPECT_EQ(engine->Stats().rejected_queue_full, 0u) << "12 jobs in a queue of 1: one place";
}

// A tick on `opencl` (BackendInfo::skins_frames_together): its float32 jobs go to the
// backend in chunks (Backend::SkinFrames). Every character is skinned right, and each
// job's compute time is its share of its chunk's, so the tick's summed compute is at most
// what its chunks took side by side (before, each job reported its whole chunk). Where no
// OpenCL platform is installed (the arm64 suite under qemu), every job is refused naming it.
TEST(EngineTest, AnOpenClTickIsSkinnedTogetherAndEachJobReportsItsShare) {
  auto engine = MakeEngine({.compute_threads = 2, .enabled_backends = {"opencl"}});
  const auto backends = engine->Backends();
  const bool opencl = std::any_of(backends.begin(), backends.end(), [](const BackendInfo& b) {
    return b.id == "opencl" && b.available;
  });
  std::vector<MeshArrays> arrays;
  std::vector<MeshInfo> infos;
  for (uint32_t m = 0; m < 4; ++m) {
    arrays.push_back(MakeSyntheticMesh(
        {.vertex_count = 1000 + 333 * m, .influences = 1 + m, .normals = true, .seed = 40 + m}));
    infos.push_back(engine->AddMesh(arrays.back()).value());
  }
  constexpr int kJobs = 16;
  std::vector<PlannedJob> jobs(kJobs);
  std::vector<std::vector<float>> palettes(kJobs), positions(kJobs), normals(kJobs);
  SkinGroup group;
  for (int i = 0; i < kJobs; ++i) {
    const MeshInfo& info = infos[i % 4];
    const uint32_t instances = i % 5 == 0 ? 2 : 1;  // a crowd now and then
    for (uint32_t k = 0; k < instances; ++k) {
      const auto one = MakeSyntheticPalette(info.joint_count, 9 + i, k);
      palettes[i].insert(palettes[i].end(), one.begin(), one.end());
    }
    positions[i].assign(3ull * info.vertex_count * instances, 0.0f);
    normals[i].assign(3ull * info.vertex_count * instances, 0.0f);
    jobs[i].request = {.mesh_id = info.id,
                       .backend = "opencl",
                       .palette = palettes[i],
                       .instances = instances,
                       .positions = positions[i],
                       .normals = normals[i]};
    group.jobs.push_back(&jobs[i]);
  }
  std::vector<Status> verdicts(kJobs);
  std::vector<std::future<Status>> done;
  for (auto& job : jobs) done.push_back(job.done.get_future());
  const auto start = std::chrono::steady_clock::now();
  engine->SubmitGroup(&group, verdicts);
  if (!opencl) {
    for (const Status& v : verdicts) {
      EXPECT_EQ(v.code(), StatusCode::kInvalidArgument) << v.ToString();
      EXPECT_NE(v.message().find("'opencl' is not available here"), std::string::npos)
          << v.message();
    }
    return;
  }
  for (int i = 0; i < kJobs; ++i) ASSERT_TRUE(verdicts[i].ok()) << verdicts[i].ToString();
  for (auto& d : done) ASSERT_TRUE(d.get().ok());
  const int64_t wall_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start)
          .count();
  int64_t compute_ns = 0;
  for (int i = 0; i < kJobs; ++i) {
    compute_ns += jobs[i].timing.compute_ns;
    auto mesh = Mesh::Create(arrays[i % 4]).value();
    const std::size_t floats = 12ull * mesh->joint_count(), values = 3ull * mesh->vertex_count();
    for (uint32_t k = 0; k < jobs[i].request.instances; ++k) {
      const Deviation d = CompareWithReference(
          *mesh, std::span<const float>(palettes[i]).subspan(k * floats, floats),
          std::span<const float>(positions[i]).subspan(k * values, values),
          std::span<const float>(normals[i]).subspan(k * values, values));
      EXPECT_TRUE(d.within_tolerance()) << "job " << i << " instance " << k;
    }
  }
  EXPECT_LE(compute_ns, 2 * wall_ns) << "the jobs' compute times add up to more than the two "
                                        "compute threads could spend in the tick's wall time";
  engine->Shutdown();
}

TEST(EngineTest, ShutdownFinishesQueuedFramesThenRefuses) {
  auto engine = MakeEngine({.compute_threads = 1});
  auto info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 5000})).value();
  std::vector<Frame> frames(20);
  std::atomic<int> ok{0};
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(engine
                    ->Submit(frames[i].Request(info, "serial", i),
                             [&](Status s, FrameTiming) { ok.fetch_add(s.ok()); })
                    .ok());
  }
  engine->Shutdown();
  EXPECT_EQ(ok.load(), 20);
  Frame late;
  EXPECT_EQ(engine->Submit(late.Request(info, "serial", 0), [](Status, FrameTiming) {}).code(),
            StatusCode::kUnavailable);
}

TEST(EngineTest, ChecksUploadShapesBeforeAllocating) {
  auto engine = MakeEngine({.mesh_budget_bytes = 1000, .mesh = {.limits = {.max_vertices = 500}}});
  EXPECT_EQ(engine->CheckMeshShape(501, 1, 1, false).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(engine->CheckMeshShape(100, 1, 1, false).code(), StatusCode::kResourceExhausted)
      << "100 vertices x 18 bytes exceed the 1000-byte budget";
  EXPECT_TRUE(engine->CheckMeshShape(50, 1, 1, false).ok());
  EXPECT_EQ(engine->CheckMeshShape(50, 9, 1, false).code(), StatusCode::kInvalidArgument);
}

// The scheduler's fairness, asserted on progress and order, not on timings: a 1.6M-vertex
// frame of a parallel backend does not hold every thread while 25k-vertex frames wait,
// and a steady flood of 25k-vertex frames does not starve it.
class SchedulerFairnessTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    engine_ = MakeEngine({.compute_threads = 2,
                          .queue_capacity = 64,
                          .enabled_backends = {kSimdOpenMpTestBackend, "openmp"}})
                  .release();
    big_ = new MeshInfo(
        engine_->AddMesh(MakeSyntheticMesh({.vertex_count = 1'600'000, .influences = 2})).value());
    small_ = new MeshInfo(
        engine_->AddMesh(MakeSyntheticMesh({.vertex_count = 25'000, .influences = 2})).value());
  }
  static void TearDownTestSuite() {
    delete engine_;
    delete big_;
    delete small_;
  }
  static Engine* engine_;
  static MeshInfo* big_;
  static MeshInfo* small_;
};
Engine* SchedulerFairnessTest::engine_ = nullptr;
MeshInfo* SchedulerFairnessTest::big_ = nullptr;
MeshInfo* SchedulerFairnessTest::small_ = nullptr;

// A large frame that, once skinned, stays on its compute thread (in OnInstanceSkinned)
// until released: while it is held, only the threads it did not take can run other frames,
// so the test sees how many it took without depending on timing.
class HeldFrameJob final : public SkinJob {
 public:
  HeldFrameJob(const MeshInfo& mesh, const std::string& backend) {
    palette_ = MakeSyntheticPalette(mesh.joint_count, 11, 0);
    positions_.assign(3ull * mesh.vertex_count, 0.0f);
    request = {mesh.id, backend, palette_, 1, positions_, {}};
  }
  std::promise<void> skinned;  // set on entering the hook
  std::promise<Status> done;
  void Release() { release_.set_value(); }

 private:
  Status OnInstanceSkinned(uint32_t, std::span<const float>, std::span<const float>) override {
    skinned.set_value();
    // The test always releases; the bound only keeps a broken test from hanging.
    if (released_.wait_for(std::chrono::minutes(2)) != std::future_status::ready) {
      return Internal("the test never released the held frame");
    }
    return Status::Ok();
  }
  void OnSkinned(Status status, const FrameTiming&) override { done.set_value(std::move(status)); }
  std::vector<float> palette_, positions_;
  std::promise<void> release_;
  std::future<void> released_ = release_.get_future();
};

TEST_F(SchedulerFairnessTest, ALargeFrameDoesNotHoldEveryThreadWhileSmallFramesWait) {
  // The large frame starts on an idle pool, where splitting it across every thread would
  // pay off if nothing else came; then small frames arrive while it is held on its thread.
  HeldFrameJob big(*big_, kSimdOpenMpTestBackend);
  std::future<Status> big_done = big.done.get_future();
  ASSERT_TRUE(engine_->Submit(&big).ok());
  big.skinned.get_future().wait();

  std::vector<Frame> small(20);
  std::mutex mutex;
  std::condition_variable changed;
  int small_done = 0, small_ok = 0, submitted = 0;
  Status refused;
  for (int i = 0; i < 20 && refused.ok(); ++i) {
    refused = engine_->Submit(small[i].Request(*small_, kSimdOpenMpTestBackend, i),
                              [&](Status s, FrameTiming) {
                                std::lock_guard lock(mutex);
                                ++small_done;
                                small_ok += s.ok();
                                changed.notify_all();
                              });
    submitted += refused.ok();
  }
  std::unique_lock lock(mutex);
  // Had the large frame taken both threads, no small frame could run until it is released.
  const bool ran_beside_it =
      changed.wait_for(lock, std::chrono::seconds(30), [&] { return small_done == submitted; });
  const int done_while_held = small_done;
  lock.unlock();
  big.Release();
  EXPECT_TRUE(refused.ok()) << refused.ToString();  // 20 fit the queue (64)
  EXPECT_TRUE(ran_beside_it) << done_while_held
                             << " of 20 small frames ran while the large frame held its thread";
  EXPECT_TRUE(big_done.get().ok());
  lock.lock();
  changed.wait(lock, [&] { return small_done == submitted; });  // their buffers outlive them
  EXPECT_EQ(small_ok, 20);
  EXPECT_LE(engine_->Stats().peak_busy_threads, 2);
}

TEST_F(SchedulerFairnessTest, AFloodOfSmallFramesDoesNotStarveALargeOne) {
  constexpr int kInFlight = 8;
  constexpr int kCap = 200'000;  // far beyond what FIFO order lets pass the large frame
  std::vector<Frame> small(kInFlight);
  Frame big;
  std::atomic<bool> big_done{false};
  std::atomic<int> submitted{0};
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<int> slots;
  for (int i = 0; i < kInFlight; ++i) slots.push_back(i);
  auto submit_small = [&](int slot) {
    return engine_->Submit(small[slot].Request(*small_, "openmp", submitted.fetch_add(1)),
                           [&, slot](Status s, FrameTiming) {
                             EXPECT_TRUE(s.ok()) << s.ToString();
                             std::lock_guard lock(mutex);
                             slots.push_back(slot);
                             changed.notify_all();
                           });
  };
  {
    std::unique_lock lock(mutex);
    for (int i = 0; i < kInFlight / 2; ++i) {
      ASSERT_TRUE(submit_small(slots.back()).ok());
      slots.pop_back();
    }
  }
  ASSERT_TRUE(engine_
                  ->Submit(big.Request(*big_, "openmp", 1),
                           [&](Status s, FrameTiming) {
                             EXPECT_TRUE(s.ok()) << s.ToString();
                             std::lock_guard lock(mutex);
                             big_done.store(true);
                             changed.notify_all();
                           })
                  .ok());
  std::unique_lock lock(mutex);
  while (!big_done.load() && submitted.load() < kCap) {
    changed.wait(lock, [&] { return big_done.load() || !slots.empty(); });
    while (!big_done.load() && !slots.empty()) {
      const int slot = slots.back();
      slots.pop_back();
      ASSERT_TRUE(submit_small(slot).ok());
    }
  }
  EXPECT_TRUE(big_done.load()) << submitted.load() << " small frames passed it";
  // Let the small frames in flight finish before their buffers go.
  changed.wait(lock, [&] { return static_cast<int>(slots.size()) == kInFlight; });
}

}  // namespace
}  // namespace skinserve
