// Bad input to the runtime gets INVALID_ARGUMENT naming the field, and no job writes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pose_reference.h"
#include "skinserve/animation/blending_job.h"
#include "skinserve/animation/local_to_model_job.h"
#include "skinserve/animation/palette_job.h"

namespace skinserve::testing {
namespace {

using animation::Transform;

void ExpectInvalid(const Status& s, const std::string& names) {
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find(names), std::string::npos) << s.message() << " should name " << names;
}

class JobErrorsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto built = animation::BuildCompactClip(c_.raw, c_.skeleton);
    ASSERT_TRUE(built.ok());
    clip_ = *built;
    local_.resize(c_.skeleton.joint_count());
    weights_.resize(clip_.weight_count);
  }
  animation::SamplingJob Sampling(float t) {
    return {&c_.skeleton, &clip_, t, animation::TimeMode::kLoop, local_, weights_};
  }
  PoseCase c_ = SyntheticCase(12);
  animation::CompactClip clip_;
  std::vector<Transform> local_;
  std::vector<float> weights_;
};

TEST_F(JobErrorsTest, SamplingNamesTimeClipAndOutputs) {
  ExpectInvalid(Sampling(std::numeric_limits<float>::quiet_NaN()).Run(), "time is nan");
  ExpectInvalid(Sampling(std::numeric_limits<float>::infinity()).Run(), "time is inf");
  auto job = Sampling(0.5f);
  job.clip = nullptr;
  ExpectInvalid(job.Run(), "clip is missing");
  job = Sampling(0.5f);
  job.output = std::span<Transform>(local_).first(3);
  ExpectInvalid(job.Run(), "output has 3 transforms; the skeleton has 12 joints");
  job = Sampling(0.5f);
  job.morph_weights = {};
  ExpectInvalid(job.Run(), "morph_weights has 0 floats");
  const PoseCase other = SyntheticCase(20);  // a clip for another skeleton
  job = Sampling(0.5f);
  job.skeleton = &other.skeleton;
  ExpectInvalid(job.Run(), "was built for a skeleton of 12 joints; this one has 20");
}

TEST_F(JobErrorsTest, SamplingRejectsBeforeWriting) {
  local_[0].translation[0] = 42;
  EXPECT_FALSE(Sampling(std::numeric_limits<float>::quiet_NaN()).Run().ok());
  EXPECT_EQ(local_[0].translation[0], 42) << "a bad job must not write its output";
}

TEST_F(JobErrorsTest, BlendingNamesTheLayerAndWeight) {
  std::vector<Transform> out(local_.size());
  animation::BlendLayer layers[] = {{local_, 1.0f, false, {}}, {local_, -0.5f, false, {}}};
  ExpectInvalid((animation::BlendingJob{layers, out, {}}.Run()), "layers[1].weight is -0.5");
  layers[1].weight = std::numeric_limits<float>::quiet_NaN();
  ExpectInvalid((animation::BlendingJob{layers, out, {}}.Run()), "layers[1].weight is nan");
  layers[0].weight = 0;
  layers[1].weight = 0;
  ExpectInvalid((animation::BlendingJob{layers, out, {}}.Run()), "weights sum to 0");
  layers[1].weight = 1;
  layers[1].pose = std::span<const Transform>(local_).first(2);
  ExpectInvalid((animation::BlendingJob{layers, out, {}}.Run()), "layers[1].pose has 2 transforms");
  std::vector<animation::BlendLayer> many(animation::kMaxBlendLayers + 1,
                                          {local_, 1.0f, false, {}});
  ExpectInvalid((animation::BlendingJob{many, out, {}}.Run()), "9 layers; 1..8");
}

TEST_F(JobErrorsTest, ModelAndPaletteNameTheirSizes) {
  std::vector<animation::Affine> model(3);
  ExpectInvalid((animation::LocalToModelJob{&c_.skeleton, local_, model}.Run()),
                "model 3 matrices");
  model.resize(local_.size());
  std::vector<float> palette(11);
  ExpectInvalid((animation::PaletteJob{&c_.skeleton, model, palette}.Run()),
                "palette has 11 floats");
}

TEST(SkeletonErrors, NamesTheJoint) {
  animation::Skeleton s = animation::MakeSyntheticRig(5).skeleton;
  s.parents[2] = 3;
  ExpectInvalid(animation::ValidateSkeleton(s), "skeleton.parents[2] = 3");
  s = animation::MakeSyntheticRig(5).skeleton;
  s.rest[4].rotation[3] = 3;
  ExpectInvalid(animation::ValidateSkeleton(s), "skeleton.rest[4].rotation has length");
  s = animation::MakeSyntheticRig(5).skeleton;
  s.palette_joints[1] = 9;
  ExpectInvalid(animation::ValidateSkeleton(s), "skeleton.palette_joints[1] = 9");
}

TEST(ClipBuilderErrors, NamesTheTrackAndField) {
  const animation::SyntheticRig rig = animation::MakeSyntheticRig(5);
  animation::RawClip raw = rig.clip;
  raw.tracks[1].target = 99;
  ExpectInvalid(animation::BuildCompactClip(raw, rig.skeleton).status(),
                "tracks[1] (rotation).target = 99 is not a joint");
  raw = rig.clip;
  raw.tracks[0].times[2] = raw.tracks[0].times[1];
  ExpectInvalid(animation::BuildCompactClip(raw, rig.skeleton).status(),
                "tracks[0] (translation).times[2]");
  raw = rig.clip;
  raw.tracks[2].values[7] = std::numeric_limits<float>::quiet_NaN();
  ExpectInvalid(animation::BuildCompactClip(raw, rig.skeleton).status(),
                "tracks[2] (scale).values[7] is not finite");
  raw = rig.clip;
  raw.tracks[1].width = 3;
  ExpectInvalid(animation::BuildCompactClip(raw, rig.skeleton).status(),
                "tracks[1] (rotation).width = 3; expected 4");
  raw = rig.clip;
  raw.tracks[0].values.pop_back();
  ExpectInvalid(animation::BuildCompactClip(raw, rig.skeleton).status(),
                "tracks[0] (translation).values has");
}

}  // namespace
}  // namespace skinserve::testing
