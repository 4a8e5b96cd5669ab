// Morph targets on the OpenCL backends where their code has its own paths: the staged copy
// path (pinned memory, chunks, several lanes), frames of several threads at once on one
// prepared mesh (each lane has its own morphed buffers; a frame must never read another's),
// frames without an active target after morphed ones (the skinning kernels read the mesh's
// rest arrays again, not the lane's morphed buffers), a frame whose active list mixes zero
// weights in, and targets that move no vertex; tangents morphed with and without normal
// deltas (each kernel of morph_targets.cl) and skinned by every skinning kernel path. Every
// frame against the float64 morph reference (ReferenceMorph, then ReferenceSkin or
// ReferenceSkinDualQuaternion) within CompareWithReference's tolerance with morphs: 1e-5
// relative to the frame's scale, the morph terms |w d| counted in it; normals 1e-5 times how
// much the deltas shorten them; tangents' xyz the same, their w exact.
#include <gtest/gtest.h>

#include <limits>
#include <mutex>
#include <thread>

#include "opencl_test_support.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr uint32_t kJoints = 77;

// Which deltas a mesh's targets carry beside the positions'. With tangent deltas, or with
// tangents, the mesh has tangents.
struct Deltas {
  bool normals = true;
  bool tangents = false;       // tangent deltas (the mesh has tangents)
  bool mesh_tangents = false;  // tangents on the mesh, with or without their deltas
};

std::shared_ptr<const Mesh> MorphMesh(uint32_t vertices, uint32_t targets, double fraction,
                                      uint64_t seed, Deltas deltas = {}) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                         .influences = 4,
                                         .joint_count = kJoints,
                                         .normals = true,
                                         .tangents = deltas.tangents || deltas.mesh_tangents,
                                         .seed = seed});
  AddSyntheticMorphTargets({.targets = targets,
                            .fraction = fraction,
                            .normals = deltas.normals,
                            .tangents = deltas.tangents,
                            .seed = seed},
                           &arrays);
  auto mesh = Mesh::Create(arrays);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return mesh.ok() ? *mesh : nullptr;
}

// "" when one frame of `weights` in `method` matches the reference; else what differs.
// `tangents` (with `normals` only) asks for the frame's tangents too.
std::string MorphedFrameMismatch(Backend& backend, const PreparedMesh& prepared,
                                 SkinningMethod method, bool normals,
                                 std::span<const MorphWeight> weights, uint64_t seed,
                                 uint64_t frame, bool tangents = false) {
  const Mesh& mesh = prepared.mesh();
  std::vector<float> positions(3ull * mesh.vertex_count(), kNaN);
  std::vector<float> out_normals(normals ? 3ull * mesh.vertex_count() : 0, kNaN);
  std::vector<float> out_tangents(tangents ? 4ull * mesh.vertex_count() : 0, kNaN);
  const auto palette = method == SkinningMethod::kDualQuaternion
                           ? MakeRigidPalette(kJoints, seed, frame)
                           : MakeSyntheticPalette(kJoints, seed, frame);
  SkinFrame skin{
      .palette = palette, .positions = positions, .normals = out_normals, .tangents = out_tangents};
  skin.method = method;
  skin.morph_weights = weights;
  if (Status s = skin.Validate(mesh); !s.ok()) return "invalid frame: " + s.ToString();
  if (Status s = backend.Skin(prepared, skin); !s.ok()) return s.ToString();
  const Deviation d =
      CompareWithReference(mesh, palette, positions, out_normals, method, weights, out_tangents);
  if (d.within_tolerance()) return "";
  return std::string(MethodName(method)) + (tangents ? " with tangents" : "") +
         ": position error " + std::to_string(d.max_position_error) + " (tolerance " +
         std::to_string(d.position_tolerance) + "), normal error " +
         std::to_string(d.max_normal_error) + " (tolerance " + std::to_string(d.normal_tolerance) +
         "), tangent error " + std::to_string(d.max_tangent_error) + " (tolerance " +
         std::to_string(d.tangent_tolerance) + "), worst vertex " + std::to_string(d.worst_vertex);
}

class OpenClMorphTest : public ::testing::TestWithParam<std::string> {};

// 20011 vertices: the staged runtime (chunks of at least 1024 vertices, at most 8) skins
// them in 8 chunks after one morph of the whole frame. Frames 2 and 3 of every 4 ask for
// tangents too (their deltas morphed, their chunks read back).
TEST_P(OpenClMorphTest, MorphedAndPlainFramesAlternateOnOnePreparedMesh) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 32;
  auto mesh = MorphMesh(20011, kTargets, 0.3, 5, {.tangents = true});
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    for (uint64_t frame = 0; frame < 12; ++frame) {
      // Morphed (1, 4 or all 32 active), then plain; every fourth frame without normals.
      std::vector<MorphWeight> weights;
      if (frame % 2 == 0) {
        const uint32_t active = frame % 6 == 0 ? 1 : (frame % 6 == 2 ? 4 : kTargets);
        weights = MakeMorphWeights(kTargets, active, 5, frame);
      }
      const bool normals = frame % 4 != 1, tangents = frame % 4 >= 2;
      EXPECT_EQ(
          MorphedFrameMismatch(backend, **prepared, method, normals, weights, 5, frame, tangents),
          "")
          << GetParam() << " frame " << frame;
    }
  }
}

// Zero weights among the active ones are skipped, not added (nor do they stop the list).
TEST_P(OpenClMorphTest, ZeroWeightsAmongActiveOnesAreSkipped) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  auto mesh = MorphMesh(3001, 8, 0.5, 6);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const std::vector<MorphWeight> weights = {{2, 0.0f}, {5, 1.25f}, {0, -0.0f}, {7, -0.75f}};
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    EXPECT_EQ(MorphedFrameMismatch(backend, **prepared, method, true, weights, 6, 0), "");
  }
}

// Targets that move no vertex: a mesh with targets but no deltas at all (nothing to put on
// the device), and weights for them leave the rest arrays as they are.
TEST_P(OpenClMorphTest, TargetsThatMoveNoVertexLeaveTheRestShape) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = 777, .influences = 2, .joint_count = kJoints, .normals = true, .seed = 8});
  arrays.morph_target_sizes = {0, 0, 0};
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const std::vector<MorphWeight> weights = {{1, 0.5f}, {2, -1.0f}};
  EXPECT_EQ(MorphedFrameMismatch(backend, **prepared, SkinningMethod::kLinear, true, weights, 8, 0),
            "");
}

// Tangents whose targets move them but not the normals (morph_positions_tangents, then the
// normals straight from the mesh), and tangents the targets do not move while they move the
// normals (morph_positions_normals, then the tangents straight from the mesh), in both
// methods; 3001 vertices (3 staged chunks, a tail of a work-group).
TEST_P(OpenClMorphTest, TangentsWithAndWithoutTheirOwnDeltasMatchTheReference) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 8;
  const Deltas kinds[] = {{.normals = false, .tangents = true},
                          {.normals = true, .tangents = false, .mesh_tangents = true}};
  for (const Deltas& deltas : kinds) {
    auto mesh = MorphMesh(3001, kTargets, 0.5, 10, deltas);
    ASSERT_NE(mesh, nullptr);
    ASSERT_EQ(mesh->has_morph_tangents(), deltas.tangents);
    ASSERT_EQ(mesh->has_morph_normals(), deltas.normals);
    auto prepared = backend.Prepare(mesh);
    ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
    const auto weights = MakeMorphWeights(kTargets, 5, 10, 0);
    for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
      EXPECT_EQ(MorphedFrameMismatch(backend, **prepared, method, true, weights, 10, 1, true), "")
          << "normal deltas " << deltas.normals << ", tangent deltas " << deltas.tangents;
    }
  }
}

// Targets that each move one region (a face rig's): spans that start and end inside a
// work-item's 256 vertices, straddle items, cover the first or the last vertex alone, or
// two neighbours across an item boundary; the kernel skips the items a span misses.
TEST_P(OpenClMorphTest, TargetsThatMoveOneRegionMatchTheReference) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 2049;
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = kVertices,
                                         .influences = 4,
                                         .joint_count = kJoints,
                                         .normals = true,
                                         .seed = 9});
  const std::vector<std::pair<uint32_t, uint32_t>> spans = {
      {0, 1}, {0, 10}, {300, 700}, {255, 257}, {511, 1537}, {kVertices - 1, kVertices}, {0, 2049}};
  for (std::size_t t = 0; t < spans.size(); ++t) {
    const auto [first, end] = spans[t];
    arrays.morph_target_sizes.push_back(end - first);
    for (uint32_t v = first; v < end; ++v) {
      arrays.morph_indices.push_back(v);
      for (int a = 0; a < 3; ++a) {
        // Distinct per target, vertex and axis, small against the unit normals.
        const float x = static_cast<float>((v * 7 + t * 13 + a * 5) % 17) / 17.0f - 0.5f;
        arrays.morph_position_deltas.push_back(0.2f * x);
        arrays.morph_normal_deltas.push_back(0.1f * x);
      }
    }
  }
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (uint32_t t = 0; t < spans.size(); ++t) {  // each target alone, then all but the last
    const std::vector<MorphWeight> alone = {{t, 1.5f}};
    EXPECT_EQ(MorphedFrameMismatch(backend, **prepared, SkinningMethod::kLinear, true, alone, 9, t),
              "")
        << "target " << t << " alone";
  }
  std::vector<MorphWeight> together;
  for (uint32_t t = 0; t + 1 < spans.size(); ++t) together.push_back({t, 0.5f - 0.25f * t});
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    EXPECT_EQ(MorphedFrameMismatch(backend, **prepared, method, true, together, 9, 20), "");
  }
}

// Threads each with their own weights (and every other frame none) on one prepared mesh:
// on the staged runtime frames run on four lanes at once, each lane with its own buffers.
TEST_P(OpenClMorphTest, ConcurrentFramesWithTheirOwnWeightsAreAllCorrect) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 16;
  constexpr int kThreads = 4, kFramesPerThread = 8;
  auto mesh = MorphMesh(12007, kTargets, 0.2, 7, {.tangents = true});
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int f = 0; f < kFramesPerThread; ++f) {
        const uint64_t frame = 100 * t + f;
        const auto weights = (f + t) % 2 == 0 ? MakeMorphWeights(kTargets, 1 + t * 5, 7, frame)
                                              : std::vector<MorphWeight>();
        const auto method = f % 3 == 2 ? SkinningMethod::kDualQuaternion : SkinningMethod::kLinear;
        // Every fourth frame without normals, every other one with tangents (each lane's
        // own tangent buffers).
        std::string mismatch = MorphedFrameMismatch(backend, **prepared, method, f % 4 != 3,
                                                    weights, 7, frame, f % 2 == 0);
        if (!mismatch.empty()) {
          std::lock_guard lock(failures_mutex);
          failures.push_back("thread " + std::to_string(t) + " frame " + std::to_string(f) + ": " +
                             mismatch);
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClMorphTest, ::testing::ValuesIn(OpenClBackendIds()),
                         BackendTestName);

}  // namespace
}  // namespace skinserve::testing
