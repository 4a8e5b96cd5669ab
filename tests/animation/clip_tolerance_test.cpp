// The clip store's error tolerance (ClipBuildOptions::max_error_mm): at the default and at
// looser ones, every joint within the chosen bound of the float64 evaluation of the
// ORIGINAL channels (pose_reference, checked by pose_check), at every key time, between
// keys, before and after the clip, clamped and looping; the bytes it saves, printed; and
// tolerances outside the limits refused.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "pose_check.h"

namespace skinserve::testing {
namespace {

// The bound a clip built to `max_error_mm` is held to (compact_clip.h).
PoseBound BoundFor(float max_error_mm) {
  const double e = max_error_mm == 0 ? animation::kDefaultMaxErrorMm : max_error_mm;
  return {e / 1000.0, animation::kRelativeError, e / animation::kShellDistanceMm};
}

// Every key time of every channel, a quarter, half and 0.8 of the way to the next key,
// and times before and after the clip.
std::vector<double> EveryKeyAndBetween(const PoseCase& c) {
  std::set<double> keys;
  for (const RefChannel& ch : c.ref_clip.channels) keys.insert(ch.times.begin(), ch.times.end());
  const double d = c.ref_clip.duration;
  std::vector<double> times = {-0.3, d + 0.4};
  double previous = -1;
  for (double k : keys) {
    if (previous >= 0) {
      for (double f : {0.25, 0.5, 0.8}) times.push_back(previous + f * (k - previous));
    }
    times.push_back(k);
    previous = k;
  }
  return times;
}

double Ratio(const PoseCase& c, const animation::CompactClip& clip) {
  return static_cast<double>(clip.Serialize().size()) / static_cast<double>(GltfFloatBytes(c.raw));
}

// Clamped at every time of EveryKeyAndBetween; looped a duration later and earlier.
void ExpectWithinTolerance(const PoseCase& c, float max_error_mm) {
  auto clip = animation::BuildCompactClip(c.raw, c.skeleton, {max_error_mm});
  ASSERT_TRUE(clip.ok()) << clip.status().ToString();
  const PoseBound bound = BoundFor(max_error_mm);
  EXPECT_FLOAT_EQ(clip->max_error_mm, static_cast<float>(bound.absolute * 1000));
  const double d = c.ref_clip.duration;
  Worst worst;
  for (double time : EveryKeyAndBetween(c)) {
    const float t = static_cast<float>(time);
    ExpectPoseMatches(c, RunPose(c, *clip, t), std::clamp(double{t}, 0.0, d), bound, worst);
    if (time >= 0 && time < d) {  // looping: a duration later and earlier samples as t
      for (double shift : {d, -d}) {
        const float looped = static_cast<float>(time + shift);
        const double wrapped = std::fmod(std::fmod(double{looped}, d) + d, d);
        ExpectPoseMatches(c, RunPose(c, *clip, looped, animation::TimeMode::kLoop), wrapped, bound,
                          worst);
      }
    }
    if (::testing::Test::HasFailure()) break;  // one time's failures say enough
  }
  int packed = 0;
  for (const animation::CompactTrack& t : clip->tracks) packed += t.bits < 16;
  std::printf(
      "%s at %.2f mm: %zu bytes, glTF floats %zu bytes, ratio %.3f; %d of %zu tracks under 16 "
      "bits; worst joint %.3f of its bound, palette %.3f, 3x3 element %.2e\n",
      c.label.c_str(), bound.absolute * 1000, clip->Serialize().size(), GltfFloatBytes(c.raw),
      Ratio(c, *clip), packed, clip->tracks.size(), worst.position, worst.palette, worst.rotation);
}

class ClipTolerance : public ::testing::TestWithParam<float> {};

TEST_P(ClipTolerance, CesiumManWithinToleranceOfGltf) {
  ExpectWithinTolerance(AssetCase("CesiumMan.glb", 0), GetParam());
}
TEST_P(ClipTolerance, RiggedSimpleWithinToleranceOfGltf) {
  ExpectWithinTolerance(AssetCase("RiggedSimple.glb", 0), GetParam());
}
TEST_P(ClipTolerance, WalkingFaceWithinToleranceOfGltf) {
  ExpectWithinTolerance(AssetCase("WalkingFace.glb", 0), GetParam());
}
TEST_P(ClipTolerance, Synthetic77WithinToleranceOfChannels) {
  ExpectWithinTolerance(SyntheticCase(77), GetParam());
}
// 0: the default (0.01 mm, the target); then 0.1, 1 and 10 mm (the loosest allowed).
INSTANTIATE_TEST_SUITE_P(Tolerances, ClipTolerance, ::testing::Values(0.0f, 0.1f, 1.0f, 10.0f));

// A clip of packed keys sampled the other ways: one track at a time (no sampling plan:
// the packed formats' scalar path) and through one SamplingContext whose times go forward
// by less than a key, stay, jump back and ahead and clamp (its cached packed keys).
TEST(ClipTolerance, PackedKeysWithoutAPlanAndThroughAContext) {
  const PoseCase c = SyntheticCase(77);
  auto clip = animation::BuildCompactClip(c.raw, c.skeleton, {1.0f});
  ASSERT_TRUE(clip.ok());
  animation::CompactClip without_plan = *clip;
  without_plan.plan.reset();
  const PoseBound bound = BoundFor(1.0f);
  const double d = c.ref_clip.duration;
  Worst worst;
  for (double time : EveryKeyAndBetween(c)) {
    const float t = static_cast<float>(time);
    ExpectPoseMatches(c, RunPose(c, without_plan, t), std::clamp(double{t}, 0.0, d), bound, worst);
    if (::testing::Test::HasFailure()) return;
  }
  animation::SamplingContext context;
  std::vector<double> times;
  for (int i = 0; i < 50; ++i) times.push_back(i / 60.0);
  for (double t : {0.5, 0.5, 0.1, 1.9, 1.2, d, 3 * d, -1.0, 0.0, 0.02}) times.push_back(t);
  for (double time : times) {
    const float t = static_cast<float>(time);
    ExpectPoseMatches(c, RunPose(c, *clip, t, animation::TimeMode::kClamp, &context),
                      std::clamp(double{t}, 0.0, d), bound, worst);
    if (::testing::Test::HasFailure()) return;
  }
  std::printf("synthetic77 at 1 mm, without a plan and through a context: worst joint %.3f\n",
              worst.position);
}

// A looser tolerance stores fewer bytes: a builder that ignored it would store the same
// clip at every tolerance (and a wrong one would fail the tests above).
TEST(ClipToleranceSize, LooserToleranceStoresFewerBytes) {
  for (const PoseCase& c :
       {AssetCase("CesiumMan.glb", 0), AssetCase("RiggedSimple.glb", 0), SyntheticCase(77)}) {
    double previous = 1e9;
    for (float e : {0.01f, 0.1f, 1.0f}) {
      auto clip = animation::BuildCompactClip(c.raw, c.skeleton, {e});
      ASSERT_TRUE(clip.ok());
      const double ratio = Ratio(c, *clip);
      EXPECT_LT(ratio, previous) << c.label << " at " << e << " mm";
      previous = ratio;
    }
  }
}

// The quarter of the glTF float bytes, by bound, as measured (the figures in
// docs/serving/animation-runtime.md#size): CesiumMan reaches it at 1 mm, the synthetic
// clip at the default; RiggedSimple (3 animated tracks of 1 joint chain: 0.264 at 10 mm)
// and WalkingFace (tiny: fixed costs) do not within the limits.
TEST(ClipToleranceSize, QuarterOfGltfFloatsByBound) {
  const PoseCase cesium = AssetCase("CesiumMan.glb", 0), synthetic = SyntheticCase(77);
  auto at_1mm = animation::BuildCompactClip(cesium.raw, cesium.skeleton, {1.0f});
  auto at_default = animation::BuildCompactClip(synthetic.raw, synthetic.skeleton, {});
  ASSERT_TRUE(at_1mm.ok() && at_default.ok());
  EXPECT_LE(Ratio(cesium, *at_1mm), 0.25);
  EXPECT_LE(Ratio(synthetic, *at_default), 0.25);
}

TEST(ClipToleranceSize, ToleranceOutsideLimitsRefusedNamingField) {
  const PoseCase c = SyntheticCase(20);
  for (float e : {-1.0f, 0.005f, 10.5f, std::numeric_limits<float>::quiet_NaN(),
                  std::numeric_limits<float>::infinity()}) {
    auto clip = animation::BuildCompactClip(c.raw, c.skeleton, {e});
    ASSERT_FALSE(clip.ok()) << e;
    EXPECT_EQ(clip.status().code(), StatusCode::kInvalidArgument) << e;
    EXPECT_NE(clip.status().message().find("max_error_mm"), std::string::npos)
        << clip.status().ToString();
    EXPECT_NE(clip.status().message().find("[0.01, 10] mm"), std::string::npos)
        << clip.status().ToString();
  }
}

// The same clip at two tolerances is two clips (the bound is part of the bytes and id).
TEST(ClipToleranceSize, ToleranceIsPartOfTheId) {
  const PoseCase c = SyntheticCase(20);
  auto a = animation::BuildCompactClip(c.raw, c.skeleton, {});
  auto b = animation::BuildCompactClip(c.raw, c.skeleton, {0.01f});
  auto d = animation::BuildCompactClip(c.raw, c.skeleton, {1.0f});
  ASSERT_TRUE(a.ok() && b.ok() && d.ok());
  EXPECT_EQ(a->id, b->id) << "0 is the default, 0.01 mm";
  EXPECT_NE(a->id, d->id);
}

}  // namespace
}  // namespace skinserve::testing
