#include "backends/common/morph_stage.h"

#include <algorithm>
#include <cstring>

#include "backends/common/morph_delta_kernel.h"
#include "skinserve/model/aligned_buffer.h"

namespace skinserve {
namespace {

// Per thread: one chunk of the morphed rest arrays, 3 floats per vertex each (4 for
// tangents). Grown to the largest seen, never shrunk.
float* ThreadMorphScratch(std::size_t floats) {
  thread_local AlignedBuffer<float> scratch;
  if (scratch.size() < floats) scratch = AlignedBuffer<float>(floats);
  return scratch.data();
}

std::vector<MorphWalk::Target>* ThreadTargets() {
  thread_local std::vector<MorphWalk::Target> targets;
  return &targets;
}

}  // namespace

MorphWalk::MorphWalk(const Mesh& mesh, const SkinFrame& frame, std::size_t first)
    : mesh_(mesh), targets_(ThreadTargets()) {
  normals_ = frame.wants_normals();
  morph_normals_ = normals_ && mesh.has_morph_normals();
  tangents_ = frame.wants_tangents();
  morph_tangents_ = tangents_ && mesh.has_morph_tangents();
  constexpr std::size_t kVec3 = 3 * kMorphChunkVertices, kVec4 = 4 * kMorphChunkVertices;
  float* scratch =
      ThreadMorphScratch(kVec3 + (morph_normals_ ? kVec3 : 0) + (morph_tangents_ ? kVec4 : 0));
  scratch_positions_ = scratch;
  if (morph_normals_) scratch_normals_ = scratch + kVec3;
  if (morph_tangents_) scratch_tangents_ = scratch + (morph_normals_ ? 2 * kVec3 : kVec3);
  targets_->clear();  // keeps its capacity
  const std::span<const uint32_t> offsets = mesh.morph_offsets();
  const uint32_t* indices = mesh.morph_indices().data();
  for (const MorphWeight& w : frame.morph_weights) {
    if (w.weight == 0.0f) continue;
    const uint32_t* begin = indices + offsets[w.target];
    const uint32_t* end = indices + offsets[w.target + 1];
    const uint32_t* next = std::lower_bound(begin, end, static_cast<uint32_t>(first));
    if (next == end) continue;
    targets_->push_back({next, end, offsets[w.target], begin, w.weight});
  }
}

bool MorphWalk::Touches(std::size_t last) const {
  for (const Target& t : *targets_) {
    if (t.next != t.end && *t.next < last) return true;
  }
  return false;
}

RestArrays MorphWalk::Apply(std::size_t first, std::size_t last) {
  const std::size_t count = last - first;
  std::memcpy(scratch_positions_, mesh_.positions().data() + 3 * first, 3 * count * sizeof(float));
  if (morph_normals_) {
    std::memcpy(scratch_normals_, mesh_.normals().data() + 3 * first, 3 * count * sizeof(float));
  }
  if (morph_tangents_) {
    std::memcpy(scratch_tangents_, mesh_.tangents().data() + 4 * first, 4 * count * sizeof(float));
  }
  const float* dp = mesh_.morph_position_deltas().data();
  const float* dn = mesh_.morph_normal_deltas().data();
  const float* dt = mesh_.morph_tangent_deltas().data();
  // Targets in the frame's order, each vertex's deltas summed in that order.
  for (Target& t : *targets_) {
    const std::size_t delta = t.first_delta + static_cast<std::size_t>(t.next - t.begin);
    t.next = AddMorphDeltas({.next = t.next,
                             .end = t.end,
                             .first = first,
                             .last = last,
                             .weight = t.weight,
                             .position_deltas = dp + 3 * delta,
                             .normal_deltas = morph_normals_ ? dn + 3 * delta : nullptr,
                             .tangent_deltas = morph_tangents_ ? dt + 3 * delta : nullptr,
                             .positions = scratch_positions_,
                             .normals = scratch_normals_,
                             .tangents = scratch_tangents_});
  }
  RestArrays rest{
      .positions = scratch_positions_, .normals = nullptr, .tangents = nullptr, .first = first};
  if (normals_) {
    rest.normals = morph_normals_ ? scratch_normals_ : mesh_.normals().data() + 3 * first;
  }
  if (tangents_) {
    rest.tangents = morph_tangents_ ? scratch_tangents_ : mesh_.tangents().data() + 4 * first;
  }
  return rest;
}

}  // namespace skinserve
