// Clip sampling and skin palettes against the test's own float64 evaluation of the glTF
// formulas (gltf_test_support.cpp), on the repository's test characters and on hand-built ones for
// the interpolations the assets lack (CUBICSPLINE).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

#include "gltf_test_support.h"
#include "skinserve/character/animation.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/reference/reference.h"

namespace skinserve::testing {
namespace {

// Tolerances. Keys are float32; the code under test interpolates in double and stores
// float32, so values agree to float32 rounding: 5e-7 relative to (1 + |value|). The palette
// composes the float32 TRS of up to ~8 levels in double and rounds once: 1e-6 relative to
// (1 + the largest palette entry). Both pass at a fifth of that (measured), so they leave
// room for other compilers without hiding a wrong formula.
constexpr double kValueTolerance = 5e-7;
constexpr double kPaletteTolerance = 1e-6;

double MaxAbs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::fabs(x));
  return m;
}

void ExpectPoseMatches(const Pose& pose, const RefCharacter& ref, const RefClip& clip, double t) {
  for (const RefChannel& ch : clip.channels) {
    const std::vector<double> expected = RefSample(ch, t);
    const CharacterNode& n = pose[static_cast<std::size_t>(ch.node)];
    if (ch.path == "rotation") {
      const double q[4] = {n.rotation.x, n.rotation.y, n.rotation.z, n.rotation.w};
      EXPECT_LT(QuatDistance(q, expected.data()), kValueTolerance)
          << "t " << t << " node " << ch.node << " rotation";
    } else {
      const glm::vec3& v = ch.path == "translation" ? n.translation : n.scale;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(v[c], expected[static_cast<std::size_t>(c)],
                    kValueTolerance * (1 + std::fabs(expected[static_cast<std::size_t>(c)])))
            << "t " << t << " node " << ch.node << " " << ch.path << "[" << c << "]";
      }
    }
  }
  (void)ref;
}

void ExpectPaletteMatches(const std::vector<float>& palette, const std::vector<double>& expected,
                          double t) {
  ASSERT_EQ(palette.size(), expected.size());
  const double tolerance = kPaletteTolerance * (1 + MaxAbs(expected));
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_NEAR(palette[i], expected[i], tolerance)
        << "t " << t << " joint " << i / 12 << " row " << i % 12 / 4 << " col " << i % 4;
  }
}

// Times that hit keys exactly, fall between them, and lie outside the clip.
std::vector<double> TestTimes(const RefClip& clip) {
  std::vector<double> times = {-0.5, 0.0, clip.duration, clip.duration + 1.0};
  for (const RefChannel& ch : clip.channels) {
    if (ch.times.size() < 4) continue;
    for (std::size_t k : {std::size_t{1}, ch.times.size() / 2, ch.times.size() - 2}) {
      times.push_back(ch.times[k]);                                          // on a key
      times.push_back(0.5 * (ch.times[k] + ch.times[k + 1]));                // halfway
      times.push_back(ch.times[k] + 0.3 * (ch.times[k + 1] - ch.times[k]));  // elsewhere
    }
    break;
  }
  for (int i = 1; i < 8; ++i) times.push_back(clip.duration * i / 7.3);
  return times;
}

class AssetAnimationTest : public ::testing::TestWithParam<const char*> {};

// The rest pose's palette puts every vertex where the file has it: model(joint) is the
// inverse of its inverse bind matrix. Skinned by the float64 reference; tolerance 2e-6 *
// (1 + max |p|), as the reference allows a float32 palette (CompareWithReference).
TEST_P(AssetAnimationTest, BindPoseSkinsToRestPositions) {
  REQUIRE_ASSET(GetParam());
  auto character = LoadGltfFile(AssetPath(GetParam()));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const SkinnedPrimitive& p = character->primitives[0];
  auto palette = SkinPalette(*character, RestPose(*character), p.skin);
  ASSERT_TRUE(palette.ok()) << palette.status().ToString();
  auto mesh = Mesh::Create(p.arrays).value();
  const ReferenceFrame frame = ReferenceSkin(*mesh, *palette);
  double max_p = 0;
  for (float x : p.arrays.positions) max_p = std::max(max_p, double{std::fabs(x)});
  const double tolerance = 2e-6 * (1 + max_p);
  double worst = 0;
  for (std::size_t i = 0; i < frame.positions.size(); ++i) {
    worst = std::max(worst, std::fabs(frame.positions[i] - p.arrays.positions[i]));
  }
  EXPECT_LE(worst, tolerance) << "largest bind-pose displacement " << worst;
  std::ostringstream text;
  text << worst << " (tolerance " << tolerance << ")";
  RecordProperty("bind_pose_max_error", text.str());
}

TEST_P(AssetAnimationTest, SamplingAndPalettesMatchFloat64Spec) {
  REQUIRE_ASSET(GetParam());
  const std::vector<uint8_t> bytes = ReadBytes(AssetPath(GetParam()));
  const RefCharacter ref = ReadReference(ParseGlb(bytes));
  auto character = LoadGltfBytes(bytes);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const AnimationClip& clip = character->clips[0];
  for (double t : TestTimes(ref.clips[0])) {
    SCOPED_TRACE(t);
    const Pose pose = SampleClip(*character, clip, t);
    ExpectPoseMatches(pose, ref, ref.clips[0], t);
    auto palette = SkinPalette(*character, pose, 0);
    ASSERT_TRUE(palette.ok()) << palette.status().ToString();
    ExpectPaletteMatches(*palette, RefPalette(ref, &ref.clips[0], t), t);
  }
  // The rest pose as well: no clip at all.
  auto rest = SkinPalette(*character, RestPose(*character), 0);
  ASSERT_TRUE(rest.ok());
  ExpectPaletteMatches(*rest, RefPalette(ref, nullptr, 0), -1);
}

INSTANTIATE_TEST_SUITE_P(Assets, AssetAnimationTest,
                         ::testing::Values("CesiumMan.glb", "RiggedSimple.glb"),
                         [](const auto& name_info) {
                           std::string name = name_info.param;
                           return name.substr(0, name.find('.'));
                         });

// Two joints; the child (node 0) comes before its parent (node 1) in the node array.
struct HandBuilt {
  Character character;
  RefCharacter ref;
};

HandBuilt MakeHandBuilt(Interpolation interpolation) {
  HandBuilt h;
  Character& c = h.character;
  c.nodes.resize(3);
  c.nodes[0].parent = 1;
  c.nodes[0].translation = {0.0f, 1.5f, 0.0f};
  c.nodes[1].parent = 2;
  c.nodes[1].rotation = glm::normalize(glm::quat(0.9f, 0.1f, -0.3f, 0.2f));
  c.nodes[2].translation = {0.25f, 0.0f, -1.0f};
  c.nodes[2].scale = {2.0f, 2.0f, 2.0f};
  CharacterSkin skin;
  skin.joints = {1, 0};
  glm::mat4 ibm0(1.0f), ibm1(1.0f);
  ibm0[3] = glm::vec4(-0.25f, 0.1f, 0.5f, 1.0f);
  ibm1[0][1] = 0.2f;  // not a rigid inverse: the palette must use it as given
  ibm1[3] = glm::vec4(0.0f, -1.5f, 0.0f, 1.0f);
  skin.inverse_bind = {ibm0, ibm1};
  c.skins.push_back(skin);

  AnimationClip clip;
  clip.name = "hand";
  const bool cubic = interpolation == Interpolation::kCubicSpline;
  auto add = [&](int node, ChannelPath path, std::vector<float> times, std::vector<float> values) {
    clip.channels.push_back({node, path, interpolation, times, values});
    clip.duration = std::max(clip.duration, times.back());
  };
  if (cubic) {  // per key: in-tangent, value, out-tangent
    add(0, ChannelPath::kTranslation, {0.0f, 0.5f, 2.0f}, {0, 0, 0,  0, 1,    0, 1,  0, 0,  //
                                                           2, 0, -1, 1, 2,    0, -3, 0, 1,  //
                                                           0, 1, 0,  0, 1.5f, 0, 0,  0, 0});
    add(1, ChannelPath::kRotation, {0.25f, 1.0f, 1.75f},
        {0,    0, 0, 0, 0,    0,          0,    1,          0.5f, 0,     0,    0,  //
         0,    1, 0, 0, 0,    0.7071068f, 0,    0.7071068f, 0,    -0.5f, 0.2f, 0,  //
         0.3f, 0, 0, 0, 0.5f, 0.5f,       0.5f, 0.5f,       0,    0,     0,    0});
    add(2, ChannelPath::kScale, {0.0f, 2.0f},
        {0, 0, 0, 1, 1, 1, 0.5f, 0, -0.5f,  //
         1, 1, 1, 2, 1, 0.5f, 0, 0, 0});
  } else {
    add(0, ChannelPath::kTranslation, {0.0f, 0.5f, 2.0f}, {0, 1, 0, 2, 0, -1, 0, 1.5f, 0});
    add(1, ChannelPath::kRotation, {0.25f, 1.0f, 1.75f},
        {0, 0, 0, 1, 0, 0.7071068f, 0, 0.7071068f, 0.5f, 0.5f, 0.5f, 0.5f});
    add(2, ChannelPath::kScale, {0.0f, 2.0f}, {1, 1, 1, 2, 1, 0.5f});
  }
  c.clips.push_back(clip);

  RefCharacter& r = h.ref;
  for (const CharacterNode& n : c.nodes) {
    RefNode rn;
    rn.parent = n.parent;
    for (int k = 0; k < 3; ++k) rn.t[k] = n.translation[k], rn.s[k] = n.scale[k];
    rn.r[0] = n.rotation.x, rn.r[1] = n.rotation.y, rn.r[2] = n.rotation.z, rn.r[3] = n.rotation.w;
    r.nodes.push_back(rn);
  }
  r.joints = skin.joints;
  for (const glm::mat4& m : skin.inverse_bind) {
    Mat4 rm;
    for (int k = 0; k < 16; ++k) rm[static_cast<std::size_t>(k)] = m[k / 4][k % 4];
    r.inverse_bind.push_back(rm);
  }
  RefClip rc;
  for (const AnimationChannel& ch : clip.channels) {
    RefChannel rch;
    rch.node = ch.node;
    rch.path = ch.path == ChannelPath::kTranslation ? "translation"
               : ch.path == ChannelPath::kRotation  ? "rotation"
                                                    : "scale";
    rch.interpolation = cubic                                   ? "CUBICSPLINE"
                        : interpolation == Interpolation::kStep ? "STEP"
                                                                : "LINEAR";
    rch.times.assign(ch.times.begin(), ch.times.end());
    rch.values.assign(ch.values.begin(), ch.values.end());
    rc.channels.push_back(rch);
  }
  rc.duration = clip.duration;
  r.clips.push_back(rc);
  return h;
}

class HandBuiltTest : public ::testing::TestWithParam<Interpolation> {};

TEST_P(HandBuiltTest, SamplingAndPalettesMatchFloat64Spec) {
  const HandBuilt h = MakeHandBuilt(GetParam());
  for (double t : {-1.0, 0.0, 0.1, 0.25, 0.4, 0.5, 0.6, 0.999, 1.0, 1.3, 1.75, 1.9, 2.0, 5.0}) {
    SCOPED_TRACE(t);
    const Pose pose = SampleClip(h.character, h.character.clips[0], t);
    ExpectPoseMatches(pose, h.ref, h.ref.clips[0], t);
    auto palette = SkinPalette(h.character, pose, 0);
    ASSERT_TRUE(palette.ok()) << palette.status().ToString();
    ExpectPaletteMatches(*palette, RefPalette(h.ref, &h.ref.clips[0], t), t);
  }
}

INSTANTIATE_TEST_SUITE_P(Interpolations, HandBuiltTest,
                         ::testing::Values(Interpolation::kLinear, Interpolation::kStep,
                                           Interpolation::kCubicSpline),
                         [](const auto& name_info) {
                           return name_info.param == Interpolation::kLinear ? "Linear"
                                  : name_info.param == Interpolation::kStep ? "Step"
                                                                            : "CubicSpline";
                         });

// Values worked out by hand, not by any code: a check on the float64 evaluator too.
TEST(AnimationTest, HandComputedValues) {
  Character c;
  c.nodes.resize(1);
  AnimationClip clip;
  // LINEAR translation (0,0,0) at 0 s to (2,4,6) at 2 s: (0.5,1,1.5) at 0.5 s.
  clip.channels.push_back(
      {0, ChannelPath::kTranslation, Interpolation::kLinear, {0, 2}, {0, 0, 0, 2, 4, 6}});
  // Identity to 90 degrees about z, the second key stored negated: the short way passes
  // 45 degrees about z at the midpoint, (0, 0, sin 22.5, cos 22.5) up to sign.
  const float h = std::sqrt(0.5f);
  clip.channels.push_back(
      {0, ChannelPath::kRotation, Interpolation::kLinear, {0, 2}, {0, 0, 0, 1, 0, 0, -h, -h}});
  // CUBICSPLINE scale from 1 to 1 over 2 s with out-tangent 1/s: at u = 0.5 the Hermite
  // basis h10 = u^3 - 2u^2 + u = 0.125, times the 2 s interval: 1 + 0.25 in x.
  clip.channels.push_back({0,
                           ChannelPath::kScale,
                           Interpolation::kCubicSpline,
                           {0, 2},
                           {0, 0, 0, 1, 1, 1, 1, 0, 0,  //
                            0, 0, 0, 1, 1, 1, 0, 0, 0}});
  const Pose pose = SampleClip(c, clip, 1.0);
  EXPECT_NEAR(pose[0].translation.x, 1.0f, 1e-6);
  EXPECT_NEAR(pose[0].translation.y, 2.0f, 1e-6);
  EXPECT_NEAR(pose[0].translation.z, 3.0f, 1e-6);
  const double expected[4] = {0, 0, std::sin(std::numbers::pi / 8), std::cos(std::numbers::pi / 8)};
  const double got[4] = {pose[0].rotation.x, pose[0].rotation.y, pose[0].rotation.z,
                         pose[0].rotation.w};
  EXPECT_LT(QuatDistance(got, expected), 1e-6);
  EXPECT_NEAR(pose[0].scale.x, 1.25f, 1e-6);
  EXPECT_NEAR(pose[0].scale.y, 1.0f, 1e-6);
  // STEP holds the earlier key until the next one, and the last key from then on.
  clip.channels[0].interpolation = Interpolation::kStep;
  EXPECT_EQ(SampleClip(c, clip, 1.999)[0].translation.y, 0.0f);
  EXPECT_EQ(SampleClip(c, clip, 2.0)[0].translation.y, 4.0f);
  EXPECT_EQ(SampleClip(c, clip, 9.0)[0].translation.y, 4.0f);
}

TEST(AnimationTest, SkinPaletteErrorsNameWhatIsWrong) {
  HandBuilt h = MakeHandBuilt(Interpolation::kLinear);
  const Pose rest = RestPose(h.character);
  EXPECT_EQ(rest.size(), 3u);
  auto bad_skin = SkinPalette(h.character, rest, 1);
  ASSERT_FALSE(bad_skin.ok());
  EXPECT_EQ(bad_skin.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad_skin.status().message().find("skin 1"), std::string::npos);
  auto bad_pose = SkinPalette(h.character, Pose(2), 0);
  ASSERT_FALSE(bad_pose.ok());
  EXPECT_NE(bad_pose.status().message().find("pose has 2 nodes"), std::string::npos);
  // A NaN time poisons the pose; the palette says so instead of skinning garbage.
  auto nan = SkinPalette(
      h.character,
      SampleClip(h.character, h.character.clips[0], std::numeric_limits<double>::quiet_NaN()), 0);
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.status().message().find("not finite"), std::string::npos);
  h.character.nodes[2].parent = 0;  // 0 -> 1 -> 2 -> 0
  auto cycle = SkinPalette(h.character, RestPose(h.character), 0);
  ASSERT_FALSE(cycle.ok());
  EXPECT_NE(cycle.status().message().find("own ancestor"), std::string::npos);
}

}  // namespace
}  // namespace skinserve::testing
