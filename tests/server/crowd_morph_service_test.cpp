// Crowds whose instances each carry their own morph weights (SkinRequest
// .instance_morph_weights) through a real server over loopback gRPC: every instance comes
// back matching a float64 morph + linear blend skinning written here (deltas summed in
// double target by target, then the blended matrix applied in double), unary and streamed,
// on every backend that applies morph targets. Bad per-instance weights are INVALID_ARGUMENT
// naming the field or the instance. Tolerance: 2e-5 of the frame's largest reference
// coordinate (plus 2e-5 absolute) per position coordinate, 2e-5 per normal component: float32
// rounds each of the ~20 terms summed per value (relative 6e-8 each), while a lost or misplaced
// target moves vertices by its delta (up to 0.1 x a weight up to 1.5).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "expect_status.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr uint32_t kJoints = 24;
constexpr uint32_t kTargets = 12;
constexpr uint32_t kInstances = 4;

MeshArrays CrowdMorphArrays() {
  MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 1201, .influences = 3, .joint_count = kJoints, .normals = true, .seed = 21});
  AddSyntheticMorphTargets({.targets = kTargets, .fraction = 0.2, .seed = 21}, &arrays);
  return arrays;
}

struct Float64Frame {
  std::vector<double> positions, normals;
};

// Morph in double (every target's deltas times its weight onto the rest arrays), then skin
// with the vertex's blended 3x4 matrix; normals by its 3x3, renormalised.
Float64Frame MorphAndSkin(const MeshArrays& a, std::span<const float> palette,
                          const std::vector<MorphWeight>& weights) {
  const std::size_t n = 3ull * a.vertex_count;
  std::vector<double> rest(a.positions.begin(), a.positions.end());
  std::vector<double> rest_normals(a.normals.begin(), a.normals.end());
  std::vector<std::size_t> first(a.morph_target_sizes.size() + 1, 0);
  for (std::size_t t = 0; t < a.morph_target_sizes.size(); ++t) {
    first[t + 1] = first[t] + a.morph_target_sizes[t];
  }
  for (const MorphWeight& w : weights) {
    for (std::size_t d = first[w.target]; d < first[w.target + 1]; ++d) {
      const std::size_t v = a.morph_indices[d];
      for (int c = 0; c < 3; ++c) {
        rest[3 * v + c] += double{w.weight} * a.morph_position_deltas[3 * d + c];
        if (!a.morph_normal_deltas.empty()) {
          rest_normals[3 * v + c] += double{w.weight} * a.morph_normal_deltas[3 * d + c];
        }
      }
    }
  }
  Float64Frame out{std::vector<double>(n), std::vector<double>(n)};
  for (std::size_t v = 0; v < a.vertex_count; ++v) {
    double m[12] = {};
    for (std::size_t i = 0; i < a.influences; ++i) {
      const double w = a.weights[v * a.influences + i];
      const std::size_t j = a.joints[v * a.influences + i];
      for (int e = 0; e < 12; ++e) m[e] += w * palette[12 * j + e];
    }
    double length = 0;
    for (int r = 0; r < 3; ++r) {
      out.positions[3 * v + r] = m[4 * r] * rest[3 * v] + m[4 * r + 1] * rest[3 * v + 1] +
                                 m[4 * r + 2] * rest[3 * v + 2] + m[4 * r + 3];
      out.normals[3 * v + r] = m[4 * r] * rest_normals[3 * v] +
                               m[4 * r + 1] * rest_normals[3 * v + 1] +
                               m[4 * r + 2] * rest_normals[3 * v + 2];
      length += out.normals[3 * v + r] * out.normals[3 * v + r];
    }
    length = std::sqrt(length);
    for (int r = 0; r < 3; ++r) out.normals[3 * v + r] /= length;
  }
  return out;
}

void ExpectInstanceMatches(const MeshArrays& a, std::span<const float> palette,
                           const std::vector<MorphWeight>& weights,
                           std::span<const float> positions, std::span<const float> normals,
                           const std::string& what) {
  const Float64Frame want = MorphAndSkin(a, palette, weights);
  ASSERT_EQ(positions.size(), want.positions.size()) << what;
  ASSERT_EQ(normals.size(), want.normals.size()) << what;
  double scale = 0;
  for (double x : want.positions) scale = std::max(scale, std::fabs(x));
  const double position_tolerance = 2e-5 * scale + 2e-5;
  double worst_position = 0, worst_normal = 0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    worst_position = std::max(worst_position, std::fabs(positions[i] - want.positions[i]));
    worst_normal = std::max(worst_normal, std::fabs(normals[i] - want.normals[i]));
  }
  EXPECT_LE(worst_position, position_tolerance) << what;
  EXPECT_LE(worst_normal, 2e-5) << what;
}

// Instance k's weights in frame f: different targets and weights per instance; instance 1
// of even frames has none at all (the rest shape beside morphed neighbours).
std::vector<MorphWeight> InstanceWeights(uint64_t frame, uint32_t k) {
  if (k == 1 && frame % 2 == 0) return {};
  return MakeMorphWeights(kTargets, 3 + k, 31 + k, frame);
}

std::vector<float> CrowdPalette(uint64_t frame) {
  std::vector<float> palettes;
  for (uint32_t k = 0; k < kInstances; ++k) {
    const auto p = MakeSyntheticPalette(kJoints, 8, frame * kInstances + k);
    palettes.insert(palettes.end(), p.begin(), p.end());
  }
  return palettes;
}

void ExpectCrowdMatches(const MeshArrays& arrays, const client::FrameResult& result,
                        const std::string& what) {
  ASSERT_TRUE(result.status.ok()) << what << ": " << result.status.ToString();
  ASSERT_EQ(result.instances, kInstances) << what;
  const std::vector<float> palettes = CrowdPalette(result.frame);
  for (uint32_t k = 0; k < kInstances; ++k) {
    ExpectInstanceMatches(
        arrays, std::span<const float>(palettes).subspan(12ull * kJoints * k, 12ull * kJoints),
        InstanceWeights(result.frame, k), result.instance_positions(k), result.instance_normals(k),
        what + " instance " + std::to_string(k));
  }
}

TEST(CrowdMorphServiceTest, EachInstanceTakesItsOwnWeightsOnEveryMorphBackend) {
  TestServer t;
  const MeshArrays arrays = CrowdMorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int backends = 0;
  for (const auto& b : list->backends()) {
    if (!b.morph_targets()) continue;
    ++backends;
    for (uint64_t frame = 0; frame < 2; ++frame) {
      std::vector<std::vector<MorphWeight>> weights;
      for (uint32_t k = 0; k < kInstances; ++k) weights.push_back(InstanceWeights(frame, k));
      const std::vector<float> palettes = CrowdPalette(frame);
      client::SkinOptions options{.backend = b.id(), .want_normals = true, .instances = kInstances};
      options.instance_morph_weights = weights;
      client::FrameResult result;
      Status s = t.client->Skin(info->mesh_id(), palettes, frame, options, &result);
      ASSERT_TRUE(s.ok()) << b.id() << ": " << s.ToString();
      result.frame = frame;
      ExpectCrowdMatches(arrays, result, b.id() + " frame " + std::to_string(frame));
    }
  }
  EXPECT_GE(backends, 4) << "serial, openmp, simd and simd-openmp at least";
}

TEST(CrowdMorphServiceTest, StreamedCrowdFramesCarryWeightsPerInstance) {
  TestServer t;
  const MeshArrays arrays = CrowdMorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  std::vector<std::vector<MorphWeight>> held(kInstances);
  client::StreamOptions options{.mesh_id = info->mesh_id(),
                                .backend = "simd-openmp",
                                .want_normals = true,
                                .instances = kInstances,
                                .frames = 6};
  options.instance_morph_weights = [&](uint64_t f) {
    for (uint32_t k = 0; k < kInstances; ++k) held[k] = InstanceWeights(f, k);
    return std::span<const std::vector<MorphWeight>>(held);
  };
  int answered = 0;
  Status s = client::StreamFrames(
      *t.client, options, [](uint64_t f) { return CrowdPalette(f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        ExpectCrowdMatches(arrays, r, "streamed frame " + std::to_string(r.frame));
        ++answered;
      });
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(answered, 6);
}

TEST(CrowdMorphServiceTest, BadInstanceWeightsAreRefusedNamingTheFieldOrInstance) {
  TestServer t;
  const MeshArrays arrays = CrowdMorphArrays();
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto skin = [&](std::vector<std::vector<MorphWeight>> weights, std::vector<MorphWeight> shared,
                  uint32_t instances) {
    std::vector<float> palettes = CrowdPalette(0);
    palettes.resize(12ull * kJoints * instances);
    client::SkinOptions options{.backend = "simd", .instances = instances};
    options.instance_morph_weights = weights;
    options.morph_weights = shared;
    client::FrameResult result;
    return t.client->Skin(info->mesh_id(), palettes, 0, options, &result);
  };
  const auto expect = [](const Status& s, const std::string& needle) {
    ExpectStatus(s, StatusCode::kInvalidArgument, needle);
  };
  expect(skin({{}, {}}, {}, 3), "instance_morph_weights holds 2 entries");
  expect(skin({{{1, 1.0f}}}, {}, 1), "instance_morph_weights holds 1 entries");
  expect(skin({{}, {}}, {{1, 1.0f}}, 2), "instance_morph_weights and morph_weights are both set");
  expect(skin({{}, {}, {{kTargets, 1.0f}}}, {}, 3),
         "instance 2: morph_weights[0]: target 12 is not below the mesh's morph_target_count 12");
  expect(skin({{{2, 1.0f}, {2, 0.5f}}, {}}, {}, 2), "instance 0: morph_weights[1]: target 2");
  // Per-instance weights for a backend without morph targets name the instance too.
  std::vector<float> palettes = CrowdPalette(0);
  palettes.resize(12ull * kJoints * 2);
  client::SkinOptions options{.backend = "passthrough", .instances = 2};
  const std::vector<std::vector<MorphWeight>> weights = {{}, {{1, 0.5f}}};
  options.instance_morph_weights = weights;
  client::FrameResult result;
  const Status s = t.client->Skin(info->mesh_id(), palettes, 0, options, &result);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
  EXPECT_NE(s.message().find("instance 1: backend 'passthrough'"), std::string::npos)
      << s.message();
}

}  // namespace
}  // namespace skinserve::testing
