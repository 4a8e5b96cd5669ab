// Backend::SkinFrames on `opencl` with output in host memory (a tick's characters): the
// frames are enqueued on one lane, each with a palette slot of its own, read back (through
// the batch's pinned memory when the runtime stages) and copied out as each completes. Every
// frame must follow its own palette, mesh and outputs, write nothing outside its arrays,
// and fail alone.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "opencl_test_support.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr std::size_t kGuardFloats = 16;  // NaN between and around the frames' arrays

// One output vector for a whole batch: each frame's positions, normals and tangents one
// after another, kGuardFloats of NaN around each array.
class BatchOutputs {
 public:
  // One more array of `floats` floats (none for 0), guarded on both sides.
  void Add(std::size_t floats) {
    if (floats == 0) return;
    const std::size_t at = size_ + kGuardFloats;
    size_ = at + floats;
    arrays_.push_back({at, floats});
  }
  // Allocates the vector (all NaN) and returns the arrays in the order they were added.
  std::vector<std::span<float>> Place() {
    floats_.assign(size_ + kGuardFloats, kNaN);
    std::vector<std::span<float>> spans;
    for (const auto& [at, n] : arrays_) spans.emplace_back(floats_.data() + at, n);
    return spans;
  }
  // Floats outside every array that are not NaN any more (written by someone).
  std::size_t TouchedOutside() const {
    std::vector<bool> inside(floats_.size(), false);
    for (const auto& [at, n] : arrays_) std::fill_n(inside.begin() + at, n, true);
    std::size_t touched = 0;
    for (std::size_t i = 0; i < floats_.size(); ++i)
      touched += !inside[i] && !std::isnan(floats_[i]);
    return touched;
  }

 private:
  std::size_t size_ = 0;
  std::vector<std::pair<std::size_t, std::size_t>> arrays_;
  std::vector<float> floats_;
};

struct Character {
  std::shared_ptr<const Mesh> mesh;
  std::vector<float> palette;
  std::vector<MorphWeight> weights;
  SkinningMethod method = SkinningMethod::kLinear;
  bool normals = false, tangents = false;
};

std::shared_ptr<const Mesh> MorphMesh(uint32_t vertices) {
  MeshArrays arrays = MakeSyntheticMesh(
      {.vertex_count = vertices, .influences = 2, .joint_count = 77, .normals = true, .seed = 5});
  AddSyntheticMorphTargets({.targets = 8, .fraction = 0.3, .seed = 5}, &arrays);
  auto mesh = Mesh::Create(arrays);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return *mesh;
}

std::shared_ptr<const Mesh> QuantizedMesh(uint32_t vertices) {
  auto mesh = Mesh::Create(
      MakeSyntheticMesh({.vertex_count = vertices, .influences = 2, .normals = true, .seed = 9}),
      {.rest_encoding = RestEncoding::kQuantized16});
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return *mesh;
}

// The test's characters for batch `round`: sizes that are no multiple of a work-group,
// positions alone, normals, tangents, dual quaternions, morph targets, and (index 3) a
// quantized mesh asked for dual quaternions, which the backend refuses for that frame only.
std::vector<Character> Characters(uint64_t round) {
  std::vector<Character> c(6);
  c[0] = {SyntheticMesh(3001, 4, 77, true, 1, true), {}, {}, SkinningMethod::kLinear, true, true};
  c[1] = {SyntheticMesh(700, 1, 77, false, 2), {}, {}, SkinningMethod::kLinear, false, false};
  c[2] = {SyntheticMesh(1500, 3, 77, true, 3), {}, {}, SkinningMethod::kDualQuaternion, true};
  c[3] = {QuantizedMesh(999), {}, {}, SkinningMethod::kDualQuaternion, true};
  c[4] = {MorphMesh(2048), {}, MakeMorphWeights(8, 3, 4, round), SkinningMethod::kLinear, true};
  c[5] = {SyntheticMesh(4099, 2, 77, true, 6), {}, {}, SkinningMethod::kLinear, true};
  for (std::size_t i = 0; i < c.size(); ++i) {
    const uint32_t joints = c[i].mesh->joint_count();
    c[i].palette = c[i].method == SkinningMethod::kDualQuaternion
                       ? MakeRigidPalette(joints, 7, 10 * round + i)
                       : MakeSyntheticPalette(joints, 7, 10 * round + i);
  }
  return c;
}

class OpenClFramesTogetherTest : public ::testing::TestWithParam<std::string> {};

TEST_P(OpenClFramesTogetherTest, EachHostFrameFollowsItsOwnPaletteMeshAndArrays) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  ASSERT_TRUE(backend.info().skins_frames_together);
  // Two batches on the same prepared meshes: the second must not see the first's palettes
  // or outputs (the lane's slots and pinned memory are reused).
  for (uint64_t round = 0; round < 2; ++round) {
    SCOPED_TRACE(::testing::Message() << "batch " << round);
    const std::vector<Character> characters = Characters(round);
    std::vector<std::unique_ptr<PreparedMesh>> kept;
    std::vector<const PreparedMesh*> prepared;
    BatchOutputs outputs;
    for (const Character& c : characters) {
      auto p = backend.Prepare(c.mesh);
      ASSERT_TRUE(p.ok()) << p.status().ToString();
      prepared.push_back(p->get());
      kept.push_back(std::move(p).value());
      const std::size_t v = c.mesh->vertex_count();
      outputs.Add(3 * v);
      outputs.Add(c.normals ? 3 * v : 0);
      outputs.Add(c.tangents ? 4 * v : 0);
    }
    const std::vector<std::span<float>> spans = outputs.Place();
    std::vector<SkinFrame> frames;
    std::size_t next = 0;
    for (const Character& c : characters) {
      SkinFrame f{.palette = c.palette, .method = c.method};
      f.positions = spans[next++];
      if (c.normals) f.normals = spans[next++];
      if (c.tangents) f.tangents = spans[next++];
      f.morph_weights = c.weights;
      ASSERT_TRUE(f.Validate(*c.mesh).ok()) << f.Validate(*c.mesh).ToString();
      frames.push_back(f);
    }
    std::vector<Status> statuses(frames.size());
    backend.SkinFrames(prepared, frames, statuses);
    for (std::size_t i = 0; i < characters.size(); ++i) {
      SCOPED_TRACE(::testing::Message() << "character " << i);
      const Character& c = characters[i];
      if (i == 3) {
        EXPECT_EQ(statuses[i].code(), StatusCode::kFailedPrecondition) << statuses[i].ToString();
        for (float x : frames[i].positions) ASSERT_TRUE(std::isnan(x)) << "a refused frame wrote";
        continue;
      }
      ASSERT_TRUE(statuses[i].ok()) << statuses[i].ToString();
      const Deviation d =
          CompareWithReference(*c.mesh, c.palette, frames[i].positions, frames[i].normals, c.method,
                               c.weights, frames[i].tangents);
      EXPECT_TRUE(d.within_tolerance()) << "position error " << d.max_position_error << ", normal "
                                        << d.max_normal_error << " at vertex " << d.worst_vertex;
    }
    EXPECT_EQ(outputs.TouchedOutside(), 0u) << "floats outside the frames' arrays were written";
  }
}

// More read-back than one batch's pinned memory holds (64 MiB): the frames run in groups,
// each group's reads landing before the next group reuses the memory.
TEST_P(OpenClFramesTogetherTest, BatchesBeyondThePinnedLimitRunInGroups) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 1'100'000;  // 26.4 MB of positions and normals a frame
  std::vector<std::shared_ptr<const Mesh>> meshes;
  std::vector<std::unique_ptr<PreparedMesh>> kept;
  std::vector<const PreparedMesh*> prepared;
  std::vector<std::vector<float>> palettes, positions, normals;
  std::vector<SkinFrame> frames;
  for (uint64_t i = 0; i < 3; ++i) {
    meshes.push_back(SyntheticMesh(kVertices, 2, 77, true, 20 + i));
    auto p = backend.Prepare(meshes.back());
    ASSERT_TRUE(p.ok()) << p.status().ToString();
    prepared.push_back(p->get());
    kept.push_back(std::move(p).value());
    palettes.push_back(MakeSyntheticPalette(77, 8, i));
    positions.emplace_back(3ull * kVertices, kNaN);
    normals.emplace_back(3ull * kVertices, kNaN);
  }
  for (std::size_t i = 0; i < 3; ++i) {
    frames.push_back({.palette = palettes[i], .positions = positions[i], .normals = normals[i]});
  }
  std::vector<Status> statuses(frames.size());
  backend.SkinFrames(prepared, frames, statuses);
  for (std::size_t i = 0; i < 3; ++i) {
    SCOPED_TRACE(::testing::Message() << "frame " << i);
    ASSERT_TRUE(statuses[i].ok()) << statuses[i].ToString();
    EXPECT_EQ(ReferenceMismatch(*meshes[i], palettes[i], positions[i], normals[i]), "");
  }
}

// The copy backend's runtimes: direct (PoCL's shared memory), staged and coalesced (the
// discrete-GPU path: pinned memory of the batch).
INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClFramesTogetherTest,
                         ::testing::Values("opencl", "opencl-staging", "opencl-coalesced"),
                         BackendTestName);

}  // namespace
}  // namespace skinserve::testing
