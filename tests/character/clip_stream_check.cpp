#include "clip_stream_check.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <span>

#include "skinserve/character/animation.h"
#include "skinserve/client/frame_stream.h"

namespace skinserve::testing {

namespace {
constexpr double kPositionTolerance = 1e-5;
constexpr double kNormalTolerance = 1e-5;
}  // namespace

uint64_t StreamClipAndCompare(client::SkinClient& client, const std::string& mesh_id,
                              const std::string& backend, const Scene& scene,
                              const Character& character, const AnimationClip& clip,
                              const CharacterMesh& mesh, const std::vector<double>& times) {
  const std::vector<ScenePrimitiveRef> prims = SkinnedPrimitives(scene);
  const bool normals = !mesh.arrays.normals.empty();
  client::StreamOptions options{
      .mesh_id = mesh_id, .backend = backend, .want_normals = normals, .frames = times.size()};
  std::vector<MorphWeight> held;
  if (!mesh.morph_sources.empty()) {
    options.morph_weights = [&](uint64_t f) {
      MeshMorphWeights(mesh, SampleClip(character, clip, times[f]), &held);
      return std::span<const MorphWeight>(held);
    };
  }
  uint64_t answered = 0;
  Status s = client::StreamFrames(
      client, options,
      [&](uint64_t f) {
        auto palette = MeshPalette(character, SampleClip(character, clip, times[f]), mesh);
        EXPECT_TRUE(palette.ok()) << palette.status().ToString();
        return palette.ok() ? *palette : std::vector<float>();
      },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        ++answered;
        ASSERT_EQ(r.positions.size(), 3u * mesh.arrays.vertex_count);
        ASSERT_EQ(r.normals.size(), normals ? r.positions.size() : 0u);
        for (const PrimitiveSpan& part : mesh.parts) {
          const RefFrame expected =
              SceneFrame(scene, prims[static_cast<std::size_t>(part.primitive)], times[r.frame]);
          ASSERT_EQ(expected.positions.size(), 3u * part.vertex_count) << part.name;
          double scale = 0;
          for (double x : expected.positions) scale = std::max(scale, std::fabs(x));
          const double tolerance = kPositionTolerance * (1 + scale);
          for (std::size_t i = 0; i < expected.positions.size(); ++i) {
            const std::size_t at = 3 * std::size_t{part.first_vertex} + i;
            ASSERT_NEAR(r.positions[at], expected.positions[i], tolerance)
                << part.name << " vertex " << i / 3 << " t " << times[r.frame];
            if (!normals) continue;
            ASSERT_NEAR(r.normals[at], expected.normals[i], kNormalTolerance)
                << part.name << " vertex " << i / 3 << " t " << times[r.frame];
          }
        }
      });
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(answered, times.size());
  return answered;
}

}  // namespace skinserve::testing
