#include "morph_stage.h"

#include <algorithm>
#include <cstring>

#include "backends/morph_delta_kernel.h"
#include "skinserve/model/aligned_buffer.h"

namespace skinserve {
namespace {

// Per thread: the morphed rest arrays, 3 floats per vertex each (4 for tangents), indexed
// like the mesh's.
// Grown to the largest mesh the thread morphed, never shrunk; only the chunks a walk
// applies are written.
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
  const std::size_t outputs = 3ull * mesh.vertex_count();
  const bool normals = !frame.normals.empty();
  morph_normals_ = normals && mesh.has_morph_normals();
  const bool tangents = !frame.tangents.empty();
  morph_tangents_ = tangents && mesh.has_morph_tangents();
  float* scratch = ThreadMorphScratch((morph_normals_ ? 2 * outputs : outputs) +
                                      (morph_tangents_ ? 4ull * mesh.vertex_count() : 0));
  positions_ = scratch;
  if (morph_tangents_) {
    scratch_tangents_ = scratch + (morph_normals_ ? 2 * outputs : outputs);
    tangents_ = scratch_tangents_;
  } else {
    tangents_ = tangents ? mesh.tangents().data() : nullptr;
  }
  if (morph_normals_) {
    scratch_normals_ = scratch + outputs;
    normals_ = scratch_normals_;
  } else {
    normals_ = normals ? mesh.normals().data() : nullptr;
  }
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

void MorphWalk::Apply(std::size_t first, std::size_t last) {
  const std::size_t count = 3 * (last - first);
  std::memcpy(positions_ + 3 * first, mesh_.positions().data() + 3 * first, count * sizeof(float));
  if (morph_normals_) {
    std::memcpy(scratch_normals_ + 3 * first, mesh_.normals().data() + 3 * first,
                count * sizeof(float));
  }
  if (morph_tangents_) {
    std::memcpy(scratch_tangents_ + 4 * first, mesh_.tangents().data() + 4 * first,
                4 * (last - first) * sizeof(float));
  }
  const float* dp = mesh_.morph_position_deltas().data();
  const float* dn = mesh_.morph_normal_deltas().data();
  const float* dt = mesh_.morph_tangent_deltas().data();
  // Targets in the frame's order, each vertex's deltas summed in that order.
  for (Target& t : *targets_) {
    const std::size_t delta = t.first_delta + static_cast<std::size_t>(t.next - t.begin);
    t.next = AddMorphDeltas({.next = t.next,
                             .end = t.end,
                             .last = last,
                             .weight = t.weight,
                             .position_deltas = dp + 3 * delta,
                             .normal_deltas = morph_normals_ ? dn + 3 * delta : nullptr,
                             .tangent_deltas = morph_tangents_ ? dt + 3 * delta : nullptr,
                             .positions = positions_,
                             .normals = scratch_normals_,
                             .tangents = scratch_tangents_});
  }
}

}  // namespace skinserve
