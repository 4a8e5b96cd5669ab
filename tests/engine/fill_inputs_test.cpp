// SkinRequest::fill_inputs_on_run: a job's palette written by SkinJob::FillInputs on the
// thread that skins the frame, once, before the backend reads it; its size checked at
// Submit, its values after FillInputs; what fails there fails the frame, named.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <future>
#include <limits>
#include <thread>

#include "skinserve/engine/engine.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

std::unique_ptr<Engine> MakeEngine(int threads) {
  auto engine = Engine::Create({.compute_threads = threads, .enabled_backends = {"serial"}});
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  return std::move(engine).value();
}

// A job whose palette is NaN until FillInputs writes `palette` (or `fill_with`'s status):
// skinned before it, or checked at Submit, the frame would fail or come out wrong.
class FillingJob final : public SkinJob {
 public:
  FillingJob(const MeshInfo& mesh, std::vector<float> palette)
      : palette_(std::move(palette)),
        room_(palette_.size(), std::numeric_limits<float>::quiet_NaN()) {
    positions.assign(3ull * mesh.vertex_count, 0.0f);
    request.mesh_id = mesh.id;
    request.backend = "serial";
    request.palette = room_;
    request.positions = positions;
    request.fill_inputs_on_run = true;
  }
  Status fill_with;                // non-OK: FillInputs fails with it
  bool fill_not_finite = false;    // FillInputs writes a NaN into the palette
  std::atomic<int> fills{0};       // FillInputs calls
  std::thread::id fill_thread;     // where FillInputs ran
  std::thread::id skinned_thread;  // where the instance's OnInstanceSkinned ran
  bool palette_filled_before_skinning = false;
  std::vector<float> positions;
  std::promise<Status> done;

 private:
  Status FillInputs() override {
    fills.fetch_add(1);
    fill_thread = std::this_thread::get_id();
    if (!fill_with.ok()) return fill_with;
    std::copy(palette_.begin(), palette_.end(), room_.begin());
    if (fill_not_finite) room_[12 * 2 + 5] = std::numeric_limits<float>::quiet_NaN();
    return Status::Ok();
  }
  Status OnInstanceSkinned(uint32_t, std::span<const float>, std::span<const float>) override {
    skinned_thread = std::this_thread::get_id();
    palette_filled_before_skinning = fills.load() == 1;
    return Status::Ok();
  }
  void OnSkinned(Status status, const FrameTiming&) override { done.set_value(status); }

  std::vector<float> palette_;
  std::vector<float> room_;
};

// A group of 24 such jobs on 2 compute threads (a tick's characters): each filled once, on
// the compute thread that skinned it (never the submitting thread), and skinned right
// against the float64 reference with the palette it filled.
TEST(FillInputsTest, EachJobFillsItsPaletteOnceOnTheThreadThatSkinsIt) {
  auto engine = MakeEngine(2);
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2000, .influences = 3});
  const MeshInfo info = engine->AddMesh(arrays).value();
  auto mesh = Mesh::Create(arrays).value();
  constexpr int kJobs = 24;
  std::vector<std::unique_ptr<FillingJob>> jobs;
  SkinGroup group;
  for (int i = 0; i < kJobs; ++i) {
    jobs.push_back(std::make_unique<FillingJob>(
        info, MakeSyntheticPalette(info.joint_count, 5 + i, static_cast<uint64_t>(i))));
    group.jobs.push_back(jobs.back().get());
  }
  std::vector<std::future<Status>> done;
  for (auto& job : jobs) done.push_back(job->done.get_future());
  std::vector<Status> verdicts(kJobs);
  engine->SubmitGroup(&group, verdicts);
  for (int i = 0; i < kJobs; ++i) {
    ASSERT_TRUE(verdicts[i].ok()) << i << ": " << verdicts[i].ToString();
    ASSERT_TRUE(done[i].get().ok()) << i;
    const FillingJob& job = *jobs[i];
    EXPECT_EQ(job.fills.load(), 1) << "job " << i;
    EXPECT_TRUE(job.palette_filled_before_skinning) << "job " << i;
    EXPECT_NE(job.fill_thread, std::this_thread::get_id()) << "job " << i;
    EXPECT_EQ(job.fill_thread, job.skinned_thread) << "job " << i;
    const auto palette = MakeSyntheticPalette(info.joint_count, 5 + i, static_cast<uint64_t>(i));
    const Deviation d = CompareWithReference(*mesh, palette, job.positions, {});
    EXPECT_TRUE(d.within_tolerance()) << "job " << i << ": " << d.max_position_error;
  }
}

TEST(FillInputsTest, WhatFailsOnTheComputeThreadFailsTheFrameNamed) {
  auto engine = MakeEngine(1);
  const MeshInfo info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 100})).value();
  const auto palette = MakeSyntheticPalette(info.joint_count, 3, 1);
  {  // FillInputs' own failure, as it said it
    FillingJob job(info, palette);
    job.fill_with = InvalidArgument("pose.layers[0]: no such thing");
    auto done = job.done.get_future();
    ASSERT_TRUE(engine->Submit(&job).ok());
    const Status s = done.get();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(s.message(), "pose.layers[0]: no such thing");
    EXPECT_EQ(job.skinned_thread, std::thread::id()) << "skinned after a failed fill";
  }
  {  // a palette filled with a value the backend must not read: checked after the fill
    FillingJob job(info, palette);
    job.fill_not_finite = true;
    auto done = job.done.get_future();
    ASSERT_TRUE(engine->Submit(&job).ok());
    const Status s = done.get();
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(
        s.message().find("the palette computed for the frame: palette[joint 2][row 1, col 1]"),
        std::string::npos)
        << s.ToString();
    EXPECT_EQ(job.skinned_thread, std::thread::id()) << "skinned a palette that is not finite";
  }
}

TEST(FillInputsTest, SubmitRefusesWhatCannotBeFilled) {
  auto engine = MakeEngine(1);
  const MeshInfo info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 100})).value();
  const auto palette = MakeSyntheticPalette(info.joint_count, 3, 1);
  FillingJob short_room(info, palette);
  short_room.request.palette = short_room.request.palette.first(12);
  Status s = engine->Submit(&short_room);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("palette to fill holds 12 floats; expected 12 * joint_count"),
            std::string::npos)
      << s.ToString();
  FillingJob crowd(info, palette);
  std::vector<float> outputs(2 * crowd.positions.size());
  crowd.request.instances = 2;
  crowd.request.positions = outputs;
  s = engine->Submit(&crowd);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("fill_inputs_on_run is set with instances = 2"), std::string::npos)
      << s.ToString();
  EXPECT_EQ(short_room.fills.load() + crowd.fills.load(), 0);
  SkinRequest no_job = short_room.request;
  no_job.palette = palette;
  EXPECT_EQ(engine->Submit(no_job, [](Status, FrameTiming) {}).code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace skinserve
