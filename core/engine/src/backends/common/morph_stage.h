// The morph stage: a frame's active morph targets added to the rest positions, normals and
// tangents (xyz; w is never morphed) before skinning, the same for every CPU loop and method. The
// vertices go chunk by chunk: a chunk that an active target moves is copied into the calling
// thread's scratch (one chunk long, so it stays in L1), the targets' sparse deltas are
// scatter-added to it, and the loop skins the chunk from there; chunks no active target moves,
// and whole frames without an active target, are skinned from the mesh's own arrays at no extra
// cost.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve {

// Vertices per chunk: a chunk's positions and normals (12 KiB; 20 KiB with tangents) stay
// in L1.
inline constexpr std::size_t kMorphChunkVertices = 512;

// The rest arrays a loop skins a range from: index 0 of each is vertex `first` (0 for the
// mesh's own arrays, the chunk's first vertex for the morph scratch). normals / tangents are
// null when the frame does not ask for them.
struct RestArrays {
  const float* positions;
  const float* normals;
  const float* tangents;
  std::size_t first;
};

// One thread's walk over the vertices [first, last) of a frame with an active target.
// Chunks must be asked for in ascending order. Allocates only when the thread meets a
// larger mesh or more active targets than before.
class MorphWalk {
 public:
  MorphWalk(const Mesh& mesh, const SkinFrame& frame, std::size_t first);
  // Whether an active target moves a vertex in [current, last) (the chunk that starts at
  // the end of the chunks already walked).
  bool Touches(std::size_t last) const;
  // Writes the morphed rest arrays of the chunk [first, last) (at most kMorphChunkVertices)
  // into the scratch and returns them: the scratch's positions, and its normals / tangents
  // where the targets move them, else the mesh's from `first` on.
  RestArrays Apply(std::size_t first, std::size_t last);

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
  bool normals_ = false;   // the frame asks for normals
  bool tangents_ = false;  // the frame asks for tangents
  float* scratch_positions_ = nullptr;
  float* scratch_normals_ = nullptr;
  float* scratch_tangents_ = nullptr;
};

// Calls skin(RestArrays, first, last) over [first, last) of `frame` in runs of chunks: the
// mesh's arrays for runs no active target moves, the morphed scratch for each chunk one does.
template <typename Skin>
void ForEachMorphedRange(const Mesh& mesh, const SkinFrame& frame, std::size_t first,
                         std::size_t last, const Skin& skin) {
  const RestArrays own{.positions = mesh.positions().data(),
                       .normals = !frame.wants_normals() ? nullptr : mesh.normals().data(),
                       .tangents = !frame.wants_tangents() ? nullptr : mesh.tangents().data(),
                       .first = 0};
  if (!HasActiveMorph(frame.morph_weights)) {
    skin(own, first, last);
    return;
  }
  MorphWalk walk(mesh, frame, first);
  std::size_t plain = first;  // start of the run of untouched chunks not skinned yet
  for (std::size_t chunk = first; chunk < last; chunk += kMorphChunkVertices) {
    const std::size_t end = std::min(last, chunk + kMorphChunkVertices);
    if (!walk.Touches(end)) continue;
    if (plain < chunk) skin(own, plain, chunk);
    skin(walk.Apply(chunk, end), chunk, end);
    plain = end;
  }
  if (plain < last) skin(own, plain, last);
}

}  // namespace skinserve
