// End to end: each test character (tests/assets/gltf) imported, its primitive uploaded to a real
// server on loopback, palettes sampled from its clip streamed on every available backend, and the
// server's vertices compared with an independent float64 skinning of the glTF file (the
// test's own reading, sampling, hierarchy, inverse bind and linear blend).
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "gltf_test_support.h"
#include "skinserve/character/animation.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/client/frame_stream.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

// Position tolerance: 1e-5 * (1 + S), S = max |p| * max row sum of |M| + max |t| over the
// frame's float64 palette: the float32 bound every backend meets against the float64
// reference (reference.h, CompareWithReference). Measured: about 1% of it, the palette's own
// float32 rounding included. Normals: 1e-5 absolute (unit vectors), as there.
constexpr double kPositionTolerance = 1e-5;
constexpr double kNormalTolerance = 1e-5;

double FrameScale(const RefPrimitive& p, const std::vector<double>& palette) {
  double max_p = 0, max_row = 0, max_t = 0;
  for (double x : p.positions) max_p = std::max(max_p, std::fabs(x));
  for (std::size_t j = 0; j < palette.size() / 12; ++j) {
    for (std::size_t r = 0; r < 3; ++r) {
      const double* row = &palette[12 * j + 4 * r];
      max_row = std::max(max_row, std::fabs(row[0]) + std::fabs(row[1]) + std::fabs(row[2]));
      max_t = std::max(max_t, std::fabs(row[3]));
    }
  }
  return max_p * max_row + max_t;
}

class CharacterEndToEndTest : public ::testing::TestWithParam<const char*> {};

TEST_P(CharacterEndToEndTest, ServerSkinsTheClipLikeFloat64Gltf) {
  REQUIRE_ASSET(GetParam());
  const std::vector<uint8_t> bytes = ReadBytes(AssetPath(GetParam()));
  const RefCharacter ref = ReadReference(ParseGlb(bytes));
  auto character = LoadGltfBytes(bytes);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const SkinnedPrimitive& primitive = character->primitives[0];
  const AnimationClip& clip = character->clips[0];
  const RefClip& ref_clip = ref.clips[0];
  // Start, a key of the first channel, in between, the last key, and past the end.
  const RefChannel& first = ref_clip.channels[0];
  const std::vector<double> times = {0.0, first.times[first.times.size() / 2],
                                     0.37 * ref_clip.duration, ref_clip.duration,
                                     ref_clip.duration + 0.5};

  TestServer t;
  auto info = t.client->Upload(primitive.arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok()) << list.status().ToString();
  int backends_run = 0;
  double worst_position = 0, worst_normal = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    SCOPED_TRACE(backend.id());
    ++backends_run;
    uint64_t answered = 0;
    Status s = client::StreamFrames(
        *t.client,
        {.mesh_id = info->mesh_id(),
         .backend = backend.id(),
         .want_normals = true,
         .frames = times.size()},
        [&](uint64_t frame) {
          auto palette =
              SkinPalette(*character, SampleClip(*character, clip, times[frame]), primitive.skin);
          EXPECT_TRUE(palette.ok()) << palette.status().ToString();
          return palette.ok() ? *palette : std::vector<float>();
        },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          ASSERT_TRUE(r.status.ok()) << r.status.ToString();
          ++answered;
          const double time = times[r.frame];
          const std::vector<double> palette = RefPalette(ref, &ref_clip, time);
          const RefFrame expected = RefSkin(ref.primitive, palette);
          const double tolerance = kPositionTolerance * (1 + FrameScale(ref.primitive, palette));
          ASSERT_EQ(r.positions.size(), expected.positions.size());
          ASSERT_EQ(r.normals.size(), expected.normals.size());
          ASSERT_FALSE(expected.normals.empty());
          double max_position = 0, max_normal = 0;
          std::size_t worst_vertex = 0;
          for (std::size_t i = 0; i < expected.positions.size(); ++i) {
            const double e = std::fabs(r.positions[i] - expected.positions[i]);
            if (!(e <= max_position)) max_position = e, worst_vertex = i / 3;  // NaN counts
            max_normal = std::max(max_normal, std::fabs(r.normals[i] - expected.normals[i]));
          }
          EXPECT_LE(max_position, tolerance)
              << "t " << time << " s: vertex " << worst_vertex << " off by " << max_position;
          EXPECT_LE(max_normal, kNormalTolerance) << "t " << time << " s";
          worst_position = std::max(worst_position, max_position / tolerance);
          worst_normal = std::max(worst_normal, max_normal);
        });
    EXPECT_TRUE(s.ok()) << s.ToString();
    EXPECT_EQ(answered, times.size());
  }
  EXPECT_GE(backends_run, 4) << "serial, openmp, sse and sse-openmp are always available";
  RecordProperty("backends", backends_run);
  std::ostringstream text;
  text << "position error / tolerance " << worst_position << ", normal error " << worst_normal;
  RecordProperty("worst", text.str());
}

INSTANTIATE_TEST_SUITE_P(Assets, CharacterEndToEndTest,
                         ::testing::Values("CesiumMan.glb", "RiggedSimple.glb"),
                         [](const auto& name_info) {
                           std::string name = name_info.param;
                           return name.substr(0, name.find('.'));
                         });

}  // namespace
}  // namespace skinserve::testing
