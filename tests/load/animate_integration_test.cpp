// skinserve-load --animate against a real server: the frames carry a pose instead of a
// palette, of the synthetic mesh (the synthetic skeleton and clip) or of a glTF character
// (--animate FILE.glb: its skeleton and --clip), uploaded once a run, in the closed loop, the
// open loop and ticks, and every checked answer is held to the pose tests' bound against the
// clip evaluated in float64 and skinned in double (client/load/pose_check.h; a file's
// original channels and primitive as gltf_reference.h reads them, apart from the importer).
// The check itself fails an answer played one frame late, or of the wrong clip.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "gltf_pose_workload.h"
#include "load_process.h"
#include "pose_check.h"
#include "pose_workload.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"
#include "workload.h"

namespace skinserve::testing {
namespace {

// The server's animation store after a run: skeletons and clips held.
std::pair<uint64_t, uint64_t> StoredRigs(const ServerProcess& server) {
  client::SkinClient c(client::MakeChannel(server.target()));
  auto stats = c.GetServerStats();
  EXPECT_TRUE(stats.ok()) << stats.status().ToString();
  return stats.ok() ? std::pair{stats->skeletons(), stats->clips()} : std::pair{0ul, 0ul};
}

std::string Common(const ServerProcess& server) {
  return "--target " + server.target() +
         " --animate synthetic --vertices 3000 --bones 4 --warmup 0 --check-every 1";
}

// 150 frames a stream: two and a half laps of the 2 s clip at 30 fps, so the server wraps
// the second lap itself. Every frame of every backend is answered, checked and right (the
// passthrough backend answers the rest pose, checked as such); the rows say "+pose".
TEST(AnimateLoadTest, ClosedLoopPosesAreAnsweredAndMatchTheFloat64Clip) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  std::string output;
  const nlohmann::json doc =
      RunLoad(Common(server) +
                  " --backends serial,simd-openmp,passthrough --normals --tangents --streams 2"
                  " --window 3 --frames 150",
              &code, nullptr, &output);
  EXPECT_EQ(code, 0) << output;
  ASSERT_EQ(doc["results"].size(), 3u) << doc.dump();
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["pose"], true) << r.dump();
    EXPECT_EQ(r["frames"], 300) << r.dump();
    EXPECT_EQ(r["checked"], 300) << "every frame checked: " << r.dump();
  }
  const auto served = server.FramesServed();
  for (const auto& [backend, frames] : FramesReported(doc)) {  // no errors, no mismatches
    EXPECT_EQ(frames, served.at(backend)) << backend;
  }
  EXPECT_NE(output.find("serial+pose"), std::string::npos) << output;
  EXPECT_EQ(StoredRigs(server), (std::pair<uint64_t, uint64_t>{1, 1})) << "uploaded once";
}

// Open loop, answers in snorm16 (the check adds the encoding's bound): every frame sent is
// answered and every answer checked and right.
TEST(AnimateLoadTest, OpenLoopPosesAreAnsweredAndMatchTheFloat64Clip) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  const nlohmann::json doc =
      RunLoad(Common(server) +
                  " --backends simd --normals --encoding snorm16 --rate 60 --streams 2"
                  " --frames 130",
              &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
  FramesReported(doc);  // no errors, no mismatches
  const auto& r = doc["results"][0];
  EXPECT_EQ(r["pose"], true) << r.dump();
  EXPECT_EQ(r["sent"].get<uint64_t>() + r["dropped"].get<uint64_t>(), 260u) << r.dump();
  EXPECT_EQ(r["frames"], r["sent"]) << "every frame sent was answered: " << r.dump();
  EXPECT_EQ(r["checked"], r["frames"]) << r.dump();
  EXPECT_GT(r["frames"], 200) << r.dump();
}

// Ticks of 3 characters, each its own mesh, skeleton and clip (seeded --seed + c): every
// character of every tick checked and right, closed and open loop.
TEST(AnimateLoadTest, TicksCarryEachCharactersPose) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  for (const std::string loop : {"", " --rate 30"}) {
    int code = 0;
    const nlohmann::json doc = RunLoad(
        Common(server) + " --backends serial --characters-per-tick 3 --streams 2 --frames 8" + loop,
        &code);
    EXPECT_EQ(code, 0) << loop;
    ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
    FramesReported(doc);
    const auto& r = doc["results"][0];
    EXPECT_EQ(r["pose"], true) << r.dump();
    EXPECT_GT(r["frames"], 0) << r.dump();
    EXPECT_EQ(r["checked"].get<uint64_t>(), 3 * r["frames"].get<uint64_t>()) << r.dump();
  }
  EXPECT_EQ(StoredRigs(server), (std::pair<uint64_t, uint64_t>{3, 3}));
}

// What a pose cannot go with is refused before anything is sent, naming the flag.
TEST(AnimateLoadTest, RefusesWhatAPoseCannotCarry) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  for (const auto& [args, says] :
       {std::pair{" --instances 2", "--instances"},
        std::pair{" --method dual-quaternion", "dual-quaternion"},
        std::pair{" --mesh x.glb", "--mesh"}, std::pair{" --morph-targets 4", "--morph-targets"}}) {
    int code = 0;
    std::string output;
    const std::string command = Common(server) + " --backends serial --frames 2" + args;
    const nlohmann::json doc = RunLoad(command, &code, nullptr, &output);
    EXPECT_NE(code, 0) << args;
    EXPECT_TRUE(doc.empty() || doc["results"].empty()) << args << doc.dump();
    EXPECT_NE(output.find(says), std::string::npos) << args << ": " << output;
  }
}

// The check can fail: an answer of the server taken as the next frame's (a thirtieth of a
// second late) is outside the bound, as is one vertex moved by 1 mm, while the answer of
// its own frame is within it; on and around the laps' ends too.
TEST(AnimateLoadTest, ThePoseCheckFailsAnAnswerPlayedOneFrameLate) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  client::SkinClient c(client::MakeChannel(server.target()));
  load::Workload w = load::MakeWorkload(3000, 4, 77, true, 5);
  w.pose = load::MakePoseWorkload(77, 5);
  ASSERT_TRUE(load::UploadPose(c, w.pose.get(), false).ok());
  auto mesh = c.Upload(*w.arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  load::FramePose pose(*w.pose);
  for (const uint64_t f : {0u, 37u, 59u, 60u, 119u}) {
    client::FrameResult r;
    ASSERT_TRUE(
        c.SkinPose(mesh->mesh_id(), pose(f), f, {.backend = "serial", .want_normals = true}, &r)
            .ok())
        << r.status.ToString();
    load::PoseAnswer answer{f, r.encoding, r.bounds.at(0), r.positions, r.normals, {}};
    EXPECT_LE(load::PoseAnswerError(w, answer), 1.0) << "frame " << f;
    answer.frame = f + 1;
    EXPECT_GT(load::PoseAnswerError(w, answer), 3.0) << "frame " << f << " taken as the next";
    answer.frame = f;
    std::vector<float> moved = r.positions;
    moved[3 * 1234 + 1] += 1e-3f;
    answer.positions = moved;
    EXPECT_GT(load::PoseAnswerError(w, answer), 1.0) << "frame " << f << ", 1 mm off";
    moved[3 * 1234 + 1] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(std::isinf(load::PoseAnswerError(w, answer))) << "a NaN";
  }
}

const std::string kCesiumMan = std::string(SKINSERVE_TEST_ASSETS_DIR) + "/CesiumMan.glb";

std::string CommonGltf(const ServerProcess& server) {
  return "--target " + server.target() + " --animate " + kCesiumMan + " --warmup 0 --check-every 1";
}

// CesiumMan's skeleton and clip 'Anim_0' (2 s, STEP and LINEAR channels, a skin under an
// armature node): 130 frames a stream, more than two laps, every frame of every backend
// answered, checked against the file's own channels in float64 and right; rows say
// "+pose:Anim_0", the reports' clip column 'Anim_0'; the skeleton and clip stored once.
TEST(AnimateLoadTest, AGltfCharactersClipIsPlayedAndEveryFrameMatchesItsFloat64Channels) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  std::string output;
  const nlohmann::json doc =
      RunLoad(CommonGltf(server) +
                  " --backends serial,simd-openmp --normals --streams 2 --window 3 --frames 130",
              &code, nullptr, &output);
  EXPECT_EQ(code, 0) << output;
  ASSERT_EQ(doc["results"].size(), 2u) << doc.dump();
  for (const auto& r : doc["results"]) {
    EXPECT_EQ(r["pose"], true) << r.dump();
    EXPECT_EQ(r["clip"], "Anim_0") << r.dump();
    EXPECT_EQ(r["vertices"], 3273) << r.dump();
    EXPECT_EQ(r["frames"], 260) << r.dump();
    EXPECT_EQ(r["checked"], 260) << "every frame checked: " << r.dump();
    EXPECT_EQ(r["mismatches"], 0) << r.dump();
  }
  const auto served = server.FramesServed();
  for (const auto& [backend, frames] : FramesReported(doc)) {  // no errors, no mismatches
    EXPECT_EQ(frames, served.at(backend)) << backend;
  }
  EXPECT_NE(output.find("serial+pose:Anim_0"), std::string::npos) << output;
  EXPECT_EQ(StoredRigs(server), (std::pair<uint64_t, uint64_t>{1, 1})) << "uploaded once";
}

// --clip-error-mm 1: the clip goes up asking for 1 mm (the note says what the server stored
// it to), and every frame is still checked (the pose part of the bound 100 times the
// default's, as the clip's) and right; a bound past 10 mm is refused before anything runs.
TEST(AnimateLoadTest, AClipStoredToALooserErrorIsPlayedAndChecked) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  int code = 0;
  std::string output;
  const nlohmann::json doc =
      RunLoad(CommonGltf(server) + " --backends serial --frames 70 --clip-error-mm 1", &code,
              nullptr, &output);
  EXPECT_EQ(code, 0) << output;
  ASSERT_EQ(doc["results"].size(), 1u) << doc.dump();
  EXPECT_EQ(doc["results"][0]["checked"], 140) << "2 streams of 70, every frame: " << doc.dump();
  EXPECT_EQ(doc["results"][0]["mismatches"], 0) << doc.dump();
  EXPECT_NE(output.find("stored to 1 mm"), std::string::npos) << output;
  RunLoad(CommonGltf(server) + " --frames 5 --clip-error-mm 20", &code, nullptr, &output);
  EXPECT_NE(code, 0) << output;
  EXPECT_NE(output.find("--clip-error-mm"), std::string::npos) << output;
}

// The open loop (snorm16 answers: the check adds the encoding's bound) and ticks of 3
// CesiumMen (one mesh, skeleton and clip, uploaded once), closed and open loop, --clip by
// index and by name: every frame answered, checked and right.
TEST(AnimateLoadTest, AGltfClipPlaysInTheOpenLoopAndInTicks) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  for (const std::string args :
       {" --clip 0 --normals --encoding snorm16 --rate 60 --streams 2 --frames 70",
        " --clip Anim_0 --characters-per-tick 3 --streams 2 --frames 8",
        " --characters-per-tick 3 --streams 2 --frames 8 --rate 30"}) {
    int code = 0;
    const nlohmann::json doc = RunLoad(CommonGltf(server) + " --backends serial" + args, &code);
    EXPECT_EQ(code, 0) << args;
    ASSERT_EQ(doc["results"].size(), 1u) << args << doc.dump();
    FramesReported(doc);  // no errors, no mismatches
    const auto& r = doc["results"][0];
    const uint64_t per_frame = std::max<uint64_t>(1, r["characters_per_tick"].get<uint64_t>());
    EXPECT_EQ(r["clip"], "Anim_0") << args << r.dump();
    EXPECT_GT(r["frames"], 0) << args << r.dump();
    EXPECT_EQ(r["frames"], r["sent"]) << args << "every frame sent was answered: " << r.dump();
    EXPECT_EQ(r["checked"].get<uint64_t>(), per_frame * r["frames"].get<uint64_t>())
        << args << r.dump();
  }
  EXPECT_EQ(StoredRigs(server), (std::pair<uint64_t, uint64_t>{1, 1}));
}

// What --animate FILE cannot go with, or cannot check, is refused before anything is
// uploaded, naming the option or what the file lacks.
TEST(AnimateLoadTest, RefusesWhatAGltfPoseCannotCarryOrCheck) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  const std::string assets = std::string(SKINSERVE_TEST_ASSETS_DIR) + "/";
  const std::string cesium = " --animate " + kCesiumMan;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {cesium + " --vertices 100", "not with --vertices"},
      {cesium + " --primitive 0", "not with --primitive"},
      {cesium + " --normals --tangents", "not with --tangents"},
      {cesium + " --mesh " + kCesiumMan, "not with --mesh"},
      {cesium + " --instances 2", "--instances"},
      {cesium + " --clip Nope",
       "--clip 'Nope': " + kCesiumMan + " has no such clip; it has 0 'Anim_0'"},
      {cesium + " --clip 1", "--clip '1'"},
      {cesium + " --rest-encoding quantized16", "stored float32; not quantized16"},
      {" --animate " + assets + "WalkingFace.glb",
       "one skinned primitive of skin 0 without morph targets"},
      {" --animate " + assets + "CesiumMan.gltf", "binary glTF file (.glb"},
      {" --animate synthetic --clip 0", "--clip picks the clip of --animate"},
  };
  for (const auto& [args, says] : cases) {
    int code = 0;
    std::string output;
    const std::string command = "--target " + server.target() +
                                " --warmup 0 --check-every 1 --backends serial --frames 2" + args;
    const nlohmann::json doc = RunLoad(command, &code, nullptr, &output);
    EXPECT_NE(code, 0) << args;
    EXPECT_TRUE(doc.empty() || doc["results"].empty()) << args << doc.dump();
    EXPECT_NE(output.find(says), std::string::npos) << args << ": " << output;
  }
  EXPECT_EQ(StoredRigs(server), (std::pair<uint64_t, uint64_t>{0, 0})) << "nothing uploaded";
}

// The glTF check can fail: CesiumMan's answer taken as the next frame's (a thirtieth of a
// second late), or checked against the file standing in its rest pose (a clip of no
// channels: the wrong clip), or with one vertex moved by 1 mm, is outside the bound, while
// the answer of its own frame is within it; on and around the laps' ends too.
TEST(AnimateLoadTest, TheGltfPoseCheckFailsALateFrameAWrongClipAndAMovedVertex) {
  ServerProcess server;
  ASSERT_TRUE(server.ready());
  client::SkinClient c(client::MakeChannel(server.target()));
  auto w = load::MakeGltfWorkload(kCesiumMan, -1, true);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  auto pose = load::MakeGltfPoseWorkload(kCesiumMan, "");
  ASSERT_TRUE(pose.ok()) << pose.status().ToString();
  w->pose = *pose;
  ASSERT_EQ(w->pose->lap_frames, 60u);  // 2 s at 30 fps
  ASSERT_TRUE(load::UploadPose(c, w->pose.get(), false).ok());
  auto mesh = c.Upload(*w->arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  load::Workload rest = *w;  // the same workload checked against a clip of no channels
  auto still = std::make_shared<load::PoseWorkload>(*w->pose);
  auto reference = std::make_shared<load::GltfPoseReference>(*w->pose->gltf);
  reference->character.clips[reference->clip].channels.clear();
  still->gltf = reference;
  rest.pose = still;
  load::FramePose frame_pose(*w->pose);
  for (const uint64_t f : {0u, 23u, 59u, 60u, 119u}) {
    client::FrameResult r;
    ASSERT_TRUE(c.SkinPose(mesh->mesh_id(), frame_pose(f), f,
                           {.backend = "serial", .want_normals = true}, &r)
                    .ok())
        << r.status.ToString();
    load::PoseAnswer answer{f, r.encoding, r.bounds.at(0), r.positions, r.normals, {}};
    EXPECT_LE(load::PoseAnswerError(*w, answer), 1.0) << "frame " << f;
    EXPECT_GT(load::PoseAnswerError(rest, answer), 3.0) << "frame " << f << " in the rest pose";
    answer.frame = f + 1;
    EXPECT_GT(load::PoseAnswerError(*w, answer), 1.0) << "frame " << f << " taken as the next";
    answer.frame = f;
    std::vector<float> moved = r.positions;
    moved[3 * 1234 + 1] += 1e-3f;
    answer.positions = moved;
    EXPECT_GT(load::PoseAnswerError(*w, answer), 1.0) << "frame " << f << ", 1 mm off";
  }
}

}  // namespace
}  // namespace skinserve::testing
