// BlendingJob against the same formulas in float64 (blending_job.h) on poses sampled from
// the original channels: normalised weights, shortest-path rotations, additive layers.
#include <gtest/gtest.h>

#include <cmath>

#include "pose_reference.h"
#include "skinserve/animation/blending_job.h"

namespace skinserve::testing {
namespace {

using animation::Transform;

struct Local {
  double t[3], q[4], s[3];
};

// Every joint's local TRS sampled from the original channels in double.
std::vector<Local> RefLocal(const PoseCase& c, double time) {
  std::vector<Local> out;
  for (const RefNode& n : c.ref.nodes) {
    Local l;
    std::copy_n(n.t, 3, l.t);
    std::copy_n(n.r, 4, l.q);
    std::copy_n(n.s, 3, l.s);
    out.push_back(l);
  }
  for (const RefChannel& ch : c.ref_clip.channels) {
    const std::vector<double> v = RefSample(ch, time);
    Local& l = out[static_cast<std::size_t>(ch.node)];
    std::copy(v.begin(), v.end(),
              ch.path == "translation" ? l.t
              : ch.path == "rotation"  ? l.q
                                       : l.s);
  }
  return out;
}

std::vector<Transform> Sample(const PoseCase& c, const animation::CompactClip& clip, float t,
                              std::vector<float>* weights) {
  std::vector<Transform> local(c.skeleton.joint_count());
  weights->resize(clip.weight_count);
  EXPECT_TRUE(
      (animation::SamplingJob{&c.skeleton, &clip, t, animation::TimeMode::kClamp, local, *weights}
           .Run()
           .ok()));
  return local;
}

void ExpectNear(const Transform& got, const Local& want, const std::string& what) {
  EXPECT_LE(RotationAngle(got.rotation, want.q), 1e-4) << what << " rotation";
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(got.translation[c], want.t[c], 1e-5 + 1e-4 * std::fabs(want.t[c]))
        << what << " translation";
    EXPECT_NEAR(got.scale[c], want.s[c], 1e-4 * std::fabs(want.s[c])) << what << " scale";
  }
}

class BlendingJobTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto built = animation::BuildCompactClip(c_.raw, c_.skeleton);
    ASSERT_TRUE(built.ok());
    clip_ = *built;
  }
  PoseCase c_ = SyntheticCase(77);
  animation::CompactClip clip_;
};

TEST_F(BlendingJobTest, TwoLayersNormalisedMatchFloat64) {
  const float t1 = 0.37f, t2 = 1.61f;
  std::vector<float> w1, w2;
  const std::vector<Transform> a = Sample(c_, clip_, t1, &w1), b = Sample(c_, clip_, t2, &w2);
  // Weights 0.6 and 1.4: normalised, 0.3 and 0.7.
  const animation::BlendLayer layers[] = {{a, 0.6f, false, w1}, {b, 1.4f, false, w2}};
  std::vector<Transform> out(a.size());
  std::vector<float> morph(w1.size());
  ASSERT_TRUE((animation::BlendingJob{layers, out, morph}.Run().ok()));
  const std::vector<Local> ra = RefLocal(c_, t1), rb = RefLocal(c_, t2);
  for (std::size_t j = 0; j < out.size(); ++j) {
    Local want;
    double dot = 0, length = 0;
    for (int k = 0; k < 4; ++k) dot += ra[j].q[k] * rb[j].q[k];
    for (int k = 0; k < 4; ++k) {
      want.q[k] = 0.3 * ra[j].q[k] + 0.7 * (dot < 0 ? -1 : 1) * rb[j].q[k];
      length += want.q[k] * want.q[k];
    }
    for (double& q : want.q) q /= std::sqrt(length);
    for (int k = 0; k < 3; ++k) {
      want.t[k] = 0.3 * ra[j].t[k] + 0.7 * rb[j].t[k];
      want.s[k] = 0.3 * ra[j].s[k] + 0.7 * rb[j].s[k];
    }
    ExpectNear(out[j], want, "joint " + std::to_string(j));
  }
  const std::vector<double> ma = RefWeightsAt(c_, t1), mb = RefWeightsAt(c_, t2);
  for (std::size_t i = 0; i < morph.size(); ++i)
    EXPECT_NEAR(morph[i], 0.3 * ma[i] + 0.7 * mb[i], 1e-4);
}

// q and -q are one rotation: a layer of negated quaternions blends as the same pose.
TEST_F(BlendingJobTest, OppositeHemispheresTakeTheShortestPath) {
  std::vector<float> w;
  const std::vector<Transform> a = Sample(c_, clip_, 0.8f, &w);
  std::vector<Transform> negated = a;
  for (Transform& t : negated)
    for (float& q : t.rotation) q = -q;
  const animation::BlendLayer layers[] = {{a, 0.5f, false, {}}, {negated, 0.5f, false, {}}};
  std::vector<Transform> out(a.size());
  ASSERT_TRUE((animation::BlendingJob{layers, out, {}}.Run().ok()));
  const std::vector<Local> ref = RefLocal(c_, 0.8f);
  for (std::size_t j = 0; j < out.size(); ++j)
    ExpectNear(out[j], ref[j], "joint " + std::to_string(j));
}

// Additive: translation += w t, rotation = nlerp(1, q, w) * rotation, scale *= 1 + w (s - 1).
TEST_F(BlendingJobTest, AdditiveLayerAppliesOnTopScaledByItsWeight) {
  std::vector<float> w1, w2;
  const std::vector<Transform> base = Sample(c_, clip_, 0.5f, &w1),
                               delta = Sample(c_, clip_, 1.2f, &w2);
  const animation::BlendLayer layers[] = {{base, 2.0f, false, {}}, {delta, 0.4f, true, {}}};
  std::vector<Transform> out(base.size());
  ASSERT_TRUE((animation::BlendingJob{layers, out, {}}.Run().ok()));
  const std::vector<Local> rb = RefLocal(c_, 0.5f), rd = RefLocal(c_, 1.2f);
  for (std::size_t j = 0; j < out.size(); ++j) {
    Local want = rb[j];
    const double sign = rd[j].q[3] < 0 ? -1 : 1;
    double q[4] = {0.4 * sign * rd[j].q[0], 0.4 * sign * rd[j].q[1], 0.4 * sign * rd[j].q[2],
                   0.6 + 0.4 * sign * rd[j].q[3]};
    const double l = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (double& x : q) x /= l;
    const double* r = rb[j].q;  // q * r
    want.q[0] = q[3] * r[0] + q[0] * r[3] + q[1] * r[2] - q[2] * r[1];
    want.q[1] = q[3] * r[1] - q[0] * r[2] + q[1] * r[3] + q[2] * r[0];
    want.q[2] = q[3] * r[2] + q[0] * r[1] - q[1] * r[0] + q[2] * r[3];
    want.q[3] = q[3] * r[3] - q[0] * r[0] - q[1] * r[1] - q[2] * r[2];
    for (int k = 0; k < 3; ++k) {
      want.t[k] += 0.4 * rd[j].t[k];
      want.s[k] *= 1 + 0.4 * (rd[j].s[k] - 1);
    }
    ExpectNear(out[j], want, "joint " + std::to_string(j));
  }
}

// The weights alone (what the server evaluates while preparing a frame): MorphSamplingJob
// against the float64 track, looped and clamped, and BlendMorphWeights' rule in double:
// normal layers by weight / sum, additive ones added times their weight, a layer without
// weights (a clip without weights tracks) counting as zeros.
TEST_F(BlendingJobTest, MorphWeightsAloneMatchFloat64) {
  const double d = c_.ref_clip.duration;
  const float t1 = 0.37f, t2 = static_cast<float>(d + 0.61), t3 = 1.61f;
  std::vector<float> w1(clip_.weight_count), w2(clip_.weight_count), w3(clip_.weight_count);
  ASSERT_TRUE(
      (animation::MorphSamplingJob{&clip_, t1, animation::TimeMode::kClamp, w1}.Run().ok()));
  ASSERT_TRUE((animation::MorphSamplingJob{&clip_, t2, animation::TimeMode::kLoop, w2}.Run().ok()));
  ASSERT_TRUE(
      (animation::MorphSamplingJob{&clip_, t3, animation::TimeMode::kClamp, w3}.Run().ok()));
  const std::vector<double> r1 = RefWeightsAt(c_, t1), r3 = RefWeightsAt(c_, t3);
  const std::vector<double> r2 = RefWeightsAt(c_, double{t2} - d);
  ASSERT_EQ(r1.size(), w1.size());
  for (std::size_t i = 0; i < w1.size(); ++i) {
    EXPECT_NEAR(w1[i], r1[i], 1e-4) << i;
    EXPECT_NEAR(w2[i], r2[i], 1e-4) << i;
  }
  const animation::BlendLayer layers[] = {{.weight = 0.6f, .morph_weights = w1},
                                          {.weight = 1.4f, .morph_weights = w2},
                                          {.weight = 1.0f},  // no weights tracks: zeros
                                          {.weight = 0.5f, .additive = true, .morph_weights = w3}};
  std::vector<float> out(w1.size());
  ASSERT_TRUE(animation::BlendMorphWeights(layers, out).ok());
  for (std::size_t i = 0; i < out.size(); ++i)
    EXPECT_NEAR(out[i], (0.6 * r1[i] + 1.4 * r2[i]) / 3.0 + 0.5 * r3[i], 1e-4) << i;
  // A layer's weights of another size are named.
  const animation::BlendLayer bad[] = {{.weight = 1.0f, .morph_weights = std::span(w1).first(1)}};
  const Status s = animation::BlendMorphWeights(bad, out);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("layers[0].morph_weights has 1 floats"), std::string::npos)
      << s.message();
}

}  // namespace
}  // namespace skinserve::testing
