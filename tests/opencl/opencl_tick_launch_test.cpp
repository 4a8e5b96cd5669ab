// Tick launches on `opencl` (opencl_tick_launch.h, kernels/tick_skinning.cl): a tick's
// linear float32 characters, whatever their meshes, skinned in a few launches over the
// device mesh arena (opencl_mesh_arena.h). Every character must follow its own mesh,
// palette and outputs (against the float64 reference), write nothing outside its arrays,
// and run in a launch when it can; pieces and rounds of host read-back, meshes across
// arena chunks, meshes too large for the arena and freed arena space must not change that.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_mesh_arena.h"
#include "backends/opencl/opencl_tick_launch.h"
#include "opencl_test_support.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr std::size_t kGuard = 16;  // NaN floats before and after every array

struct Character {
  std::shared_ptr<const Mesh> mesh;
  bool normals = false, tangents = false;
  SkinningMethod method = SkinningMethod::kLinear;
};

// A tick of `characters` on `backend`: each with its own palette (seeded by `seed` and its
// index), outputs in one NaN-guarded vector; checks every answer against the reference and
// that nothing outside the arrays was written. Returns the frames that took tick launches.
uint64_t RunTick(Backend& backend, const std::vector<Character>& characters, uint64_t seed) {
  std::vector<std::unique_ptr<PreparedMesh>> kept;
  std::vector<const PreparedMesh*> prepared;
  std::vector<std::vector<float>> palettes;
  std::vector<std::array<std::size_t, 3>> at;  // positions, normals, tangents (or npos)
  std::size_t size = 0;
  const auto place = [&](std::size_t floats) {
    if (floats == 0) return std::string::npos;
    const std::size_t start = size + kGuard;
    size = start + floats;
    return start;
  };
  for (std::size_t i = 0; i < characters.size(); ++i) {
    const Character& c = characters[i];
    auto p = backend.Prepare(c.mesh);
    EXPECT_TRUE(p.ok()) << p.status().ToString();
    if (!p.ok()) return 0;
    prepared.push_back(p->get());
    kept.push_back(std::move(p).value());
    const uint32_t joints = c.mesh->joint_count();
    palettes.push_back(c.method == SkinningMethod::kDualQuaternion
                           ? MakeRigidPalette(joints, 7, seed + i)
                           : MakeSyntheticPalette(joints, 7, seed + i));
    const std::size_t v = c.mesh->vertex_count();
    const std::size_t p0 = place(3 * v), n0 = place(c.normals ? 3 * v : 0),
                      t0 = place(c.tangents ? 4 * v : 0);
    at.push_back({p0, n0, t0});
  }
  std::vector<float> out(size + kGuard, kNaN);
  const auto span = [&](std::size_t start, std::size_t floats) {
    return start == std::string::npos ? std::span<float>() : std::span(out).subspan(start, floats);
  };
  std::vector<SkinFrame> frames;
  for (std::size_t i = 0; i < characters.size(); ++i) {
    const std::size_t v = characters[i].mesh->vertex_count();
    frames.push_back({.palette = palettes[i],
                      .positions = span(at[i][0], 3 * v),
                      .normals = span(at[i][1], 3 * v),
                      .tangents = span(at[i][2], 4 * v),
                      .method = characters[i].method});
  }
  std::vector<Status> statuses(frames.size());
  const uint64_t before = TickLaunchFrames();
  backend.SkinFrames(prepared, frames, statuses);
  const uint64_t launched = TickLaunchFrames() - before;
  for (std::size_t i = 0; i < characters.size(); ++i) {
    SCOPED_TRACE(::testing::Message()
                 << "character " << i << " (" << characters[i].mesh->vertex_count()
                 << " vertices, B " << characters[i].mesh->influences() << ")");
    EXPECT_TRUE(statuses[i].ok()) << statuses[i].ToString();
    const Deviation d =
        CompareWithReference(*characters[i].mesh, palettes[i], frames[i].positions,
                             frames[i].normals, characters[i].method, {}, frames[i].tangents);
    EXPECT_TRUE(d.within_tolerance())
        << "position error " << d.max_position_error << ", normal " << d.max_normal_error
        << ", tangent " << d.max_tangent_error << " at vertex " << d.worst_vertex;
  }
  std::vector<bool> inside(out.size(), false);
  for (std::size_t i = 0; i < characters.size(); ++i) {
    for (std::span<float> s : {frames[i].positions, frames[i].normals, frames[i].tangents}) {
      if (!s.empty()) std::fill_n(inside.begin() + (s.data() - out.data()), s.size(), true);
    }
  }
  std::size_t touched = 0;
  for (std::size_t k = 0; k < out.size(); ++k) touched += !inside[k] && !std::isnan(out[k]);
  EXPECT_EQ(touched, 0u) << "floats outside the characters' arrays were written";
  return launched;
}

class OpenClTickLaunchTest : public ::testing::TestWithParam<std::string> {};

// Meshes of every shape a launch groups by (influences 1-4 and 8, positions alone, normals,
// tangents; 77 joints, whose palette the coalesced runtime stages in local memory, and
// 1024, which it does not), vertex counts that fill no work-group, two characters on one
// mesh, and a dual-quaternion frame among them (the per-frame path).
TEST_P(OpenClTickLaunchTest, EveryCharacterOfATickFollowsItsOwnMeshPaletteAndArrays) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  const auto tangent_mesh = SyntheticMesh(3001, 4, 77, true, 1, true);
  const std::vector<Character> characters = {
      {tangent_mesh, true, true},
      {SyntheticMesh(1, 1, 77, false, 2)},
      {SyntheticMesh(255, 2, 77, true, 3), true},
      {SyntheticMesh(1000, 3, 1024, true, 4), true},
      {SyntheticMesh(4099, 2, 77, false, 5)},
      {tangent_mesh, true, true},
      {SyntheticMesh(700, 8, 20, true, 6), true},
      {SyntheticMesh(1500, 3, 77, true, 7), true, false, SkinningMethod::kDualQuaternion},
      {SyntheticMesh(257, 2, 77, true, 8, true), true, false},  // tangents in the mesh, not asked
  };
  for (uint64_t round = 0; round < 2; ++round) {  // the lane's buffers reused
    SCOPED_TRACE(::testing::Message() << "tick " << round);
    EXPECT_EQ(RunTick(backend, characters, 100 * round), characters.size() - 1)
        << "every linear character but none other in a launch";
  }
}

// More host output than a piece (8 MiB) and than a round (64 MiB): 120 characters of 25k
// vertices with normals (72 MB) on four meshes.
TEST_P(OpenClTickLaunchTest, TicksBeyondAPieceAndARoundOfReadBack) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  std::vector<std::shared_ptr<const Mesh>> meshes;
  for (uint64_t m = 0; m < 4; ++m) meshes.push_back(SyntheticMesh(25'000, 2, 77, true, 40 + m));
  std::vector<Character> characters;
  for (std::size_t i = 0; i < 120; ++i) characters.push_back({meshes[i % 4], true});
  static_assert(120 * 25'000 * 24 > OpenClTickLaunches::kRoundBytes);
  EXPECT_EQ(RunTick(backend, characters, 7), characters.size());
}

// The copy backend's runtimes: direct (PoCL's shared memory), staged (pinned read-back on
// the transfer queue) and coalesced (the GPU's kernels, local palettes).
INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClTickLaunchTest,
                         ::testing::Values("opencl", "opencl-staging", "opencl-coalesced"),
                         BackendTestName);

// A runtime whose arena chunks hold 1 MiB: meshes of 180 KB fill several chunks, one of
// 720 KB (over a quarter of a chunk) keeps buffers of its own and runs per frame.
struct SmallArena {
  std::shared_ptr<OpenClRuntime> runtime;
  std::unique_ptr<Backend> backend;
};
SmallArena MakeSmallArena() {
  auto runtime = OpenClRuntime::Create(
      {.threads = 2, .device = OpenClTestDevice(), .mesh_arena_bytes = std::size_t{1} << 20});
  EXPECT_TRUE(runtime.ok()) << runtime.status().ToString();
  if (!runtime.ok()) return {};
  auto backends = MakeOpenClBackendsOn(*runtime);
  return {*runtime, std::move(backends.front())};
}

TEST(OpenClMeshArenaTest, MeshesAcrossChunksAndOneTooLargeForTheArena) {
  SmallArena arena = MakeSmallArena();
  ASSERT_NE(arena.backend, nullptr);
  std::vector<Character> characters;
  for (uint64_t m = 0; m < 12; ++m) {
    characters.push_back({SyntheticMesh(5000, 2, 77, true, 60 + m), true});
  }
  characters.push_back({SyntheticMesh(20'000, 2, 77, true, 99), true});
  EXPECT_EQ(RunTick(*arena.backend, characters, 3), 12u) << "all but the large mesh";
}

// Space of a freed mesh is handed to the next mesh that fits; freed neighbours merge.
TEST(OpenClMeshArenaTest, FreedSpaceIsReusedAndMerged) {
  auto runtime = OpenClRuntime::Create({.threads = 2, .device = OpenClTestDevice()});
  ASSERT_TRUE(runtime.ok()) << runtime.status().ToString();
  auto arena = OpenClMeshArena::Create(*runtime, std::size_t{1} << 20);
  const uint64_t a = arena->alignment();
  auto first = arena->Allocate(100'000), second = arena->Allocate(100'000),
       third = arena->Allocate(100'000);
  ASSERT_TRUE(first.ok() && second.ok() && third.ok());
  ASSERT_NE(*second, nullptr);
  const uint64_t second_at = (*second)->offset();
  EXPECT_EQ(second_at % a, 0u);
  EXPECT_EQ((*first)->offset(), 0u);
  second->reset();
  auto smaller = arena->Allocate(50'000);
  ASSERT_TRUE(smaller.ok() && *smaller != nullptr);
  EXPECT_EQ((*smaller)->offset(), second_at) << "first fit: the freed space";
  EXPECT_EQ(arena->Allocate((1 << 20) / 4 + 1)->get(), nullptr) << "over a quarter of a chunk";
  first->reset(), smaller->reset(), third->reset();
  // All free again and merged: the largest slice fits at the start of the one chunk.
  auto whole = arena->Allocate((1 << 20) / 4);
  ASSERT_TRUE(whole.ok() && *whole != nullptr);
  EXPECT_EQ((*whole)->offset(), 0u);
  EXPECT_EQ(arena->chunk_count(), 1u);
}

// A mesh prepared into the space another left: both meshes' characters right in one tick.
TEST(OpenClMeshArenaTest, AMeshInFreedSpaceSkinsRight) {
  SmallArena arena = MakeSmallArena();
  ASSERT_NE(arena.backend, nullptr);
  auto kept = SyntheticMesh(5000, 2, 77, true, 70);
  {
    auto gone = arena.backend->Prepare(SyntheticMesh(5000, 2, 77, true, 71));
    ASSERT_TRUE(gone.ok());
  }
  std::vector<Character> characters = {{kept, true}, {SyntheticMesh(4000, 3, 77, true, 72), true}};
  EXPECT_EQ(RunTick(*arena.backend, characters, 5), 2u);
}

}  // namespace
}  // namespace skinserve::testing
