// The morph stage: a frame's active morph targets added to the rest positions, normals and
// tangents (xyz; w is never morphed) before skinning, the same for every CPU loop and method. The
// vertices go chunk by chunk: a chunk that an active target moves is copied into the calling
// thread's scratch, the targets' sparse deltas are scatter-added to it, and the loop skins the
// chunk from there while it is still in the core's cache; chunks no active target moves, and whole
// frames without an active target, are skinned from the mesh's own arrays at no extra cost.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve {

// Vertices per chunk: a chunk's positions and normals (12 KiB; 20 KiB with tangents) stay
// in L1.
inline constexpr std::size_t kMorphChunkVertices = 512;

// One thread's walk over the vertices [first, last) of a frame with an active target.
// Chunks must be asked for in ascending order. Allocates only when the thread meets a
// larger mesh or more active targets than before.
class MorphWalk {
 public:
  MorphWalk(const Mesh& mesh, const SkinFrame& frame, std::size_t first);
  // Whether an active target moves a vertex in [current, last) (the chunk that starts at
  // the end of the chunks already walked).
  bool Touches(std::size_t last) const;
  // Writes the morphed rest arrays of [first, last) into the scratch (only those vertices;
  // the arrays are indexed by vertex like the mesh's).
  void Apply(std::size_t first, std::size_t last);
  const float* positions() const { return positions_; }
  // The scratch's normals when targets move normals, else the mesh's; null without normals.
  const float* normals() const { return normals_; }
  // The scratch's tangents when targets move tangents, else the mesh's; null without them.
  const float* tangents() const { return tangents_; }

  struct Target {
    const uint32_t* next;  // its next delta's vertex index, ascending
    const uint32_t* end;
    std::size_t first_delta;  // the delta index of *indices-begin, for the delta arrays
    const uint32_t* begin;
    float weight;
  };

 private:
  const Mesh& mesh_;
  bool morph_normals_ = false;   // normals asked for, and the targets move them
  bool morph_tangents_ = false;  // tangents asked for, and the targets move them
  std::vector<Target>* targets_;
  float* positions_ = nullptr;
  const float* normals_ = nullptr;
  float* scratch_normals_ = nullptr;
  const float* tangents_ = nullptr;
  float* scratch_tangents_ = nullptr;
};

// Calls skin(rest_positions, rest_normals, rest_tangents, first, last) over [first, last) of
// `frame` in runs of chunks: the mesh's arrays for runs no active target moves, the morphed scratch
// for each chunk one does.
template <typename Skin>
void ForEachMorphedRange(const Mesh& mesh, const SkinFrame& frame, std::size_t first,
                         std::size_t last, const Skin& skin) {
  const float* rest_p = mesh.positions().data();
  const float* rest_n = frame.normals.empty() ? nullptr : mesh.normals().data();
  const float* rest_t = frame.tangents.empty() ? nullptr : mesh.tangents().data();
  if (!HasActiveMorph(frame.morph_weights)) {
    skin(rest_p, rest_n, rest_t, first, last);
    return;
  }
  MorphWalk walk(mesh, frame, first);
  std::size_t plain = first;  // start of the run of untouched chunks not skinned yet
  for (std::size_t chunk = first; chunk < last; chunk += kMorphChunkVertices) {
    const std::size_t end = std::min(last, chunk + kMorphChunkVertices);
    if (!walk.Touches(end)) continue;
    if (plain < chunk) skin(rest_p, rest_n, rest_t, plain, chunk);
    walk.Apply(chunk, end);
    skin(walk.positions(), rest_n == nullptr ? nullptr : walk.normals(),
         rest_t == nullptr ? nullptr : walk.tangents(), chunk, end);
    plain = end;
  }
  if (plain < last) skin(rest_p, rest_n, rest_t, plain, last);
}

}  // namespace skinserve
