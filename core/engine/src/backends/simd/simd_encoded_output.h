// Encoded output written by the `simd` backends (SkinFrame::encoded, issue 29 item 2): the
// loop skins a chunk of vertices into this thread's L1 scratch and encodes it from there
// with core/encoding's own functions (EncodePositions / EncodeNormals / EncodeTangents on
// the chunk), so the bytes are the host encoder's by construction and no frame-sized float
// array is written. snorm16 positions need the frame's box first: they are skinned into a
// frame-sized float array (EncodedOutput::box_scratch, the caller's, else this thread's), boxed
// (ComputeBounds over each thread's range once it is skinned, merged) and encoded in a second pass;
// their normals and tangents go through the scratch.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "skinserve/engine/backend.h"
#include "skinserve/model/aligned_buffer.h"

namespace skinserve::simd {

// The encodings the simd backends list in BackendInfo::encoded_outputs: those where the
// direct path measured no slower than float32 then the host encoder
// (docs/results/2026-11-27-cpu-encoded-vm).
std::vector<VertexEncoding> EncodedOutputs();

class EncodedWriter {
 public:
  // Vertices per chunk: 512 x (3 + 3 + 4) floats = 20 KiB of scratch, inside L1.
  static constexpr std::size_t kChunkVertices = 512;

  // `out` as validated (SkinFrame::ValidateEncoded); `vertex_count` the mesh's.
  EncodedWriter(const EncodedOutput& out, std::size_t vertex_count);

  // Skins vertices [from, to) through skin(offset, count, positions, normals, tangents),
  // which writes vertices from + offset ... + count - 1 at index 0 of the three float
  // arrays (normals / tangents null when the frame has none), and encodes them. Callable
  // from several threads on disjoint ranges. Stops early once a value failed anywhere.
  template <typename Skin>
  void Write(std::size_t from, std::size_t to, const Skin& skin) {
    float* scratch = ThreadScratch();
    for (std::size_t c = from; c < to; c += kChunkVertices) {
      if (failed_.load(std::memory_order_relaxed)) return;
      const std::size_t count = std::min(kChunkVertices, to - c);
      float* p = boxed_ ? positions_ + 3 * c : scratch;
      float* n = wants_normals_ ? scratch + 3 * kChunkVertices : nullptr;
      float* t = wants_tangents_ ? scratch + 6 * kChunkVertices : nullptr;
      skin(c - from, count, p, n, t);
      if (!EncodeChunk(c, count, p, n, t)) {
        failed_.store(true, std::memory_order_relaxed);
        return;
      }
    }
    if (boxed_) BoxRange(from, to);
  }

  // After every Write: snorm16's box into out.bounds and its positions' second pass (split
  // across `threads`). False when some value failed its encoding: the caller then skins the
  // frame to floats and runs the host encoder, whose error names the vertex.
  bool Finish(int threads);

 private:
  static float* ThreadScratch();
  bool EncodeChunk(std::size_t first, std::size_t count, const float* p, const float* n,
                   const float* t) const;
  // snorm16: the box of positions [from, to) (ComputeBounds, while they are in this core's
  // cache) merged into the frame's.
  void BoxRange(std::size_t from, std::size_t to);

  EncodedOutput out_;
  std::size_t vertex_count_;
  bool boxed_;
  bool wants_normals_;
  bool wants_tangents_;
  float* positions_ = nullptr;  // snorm16: the frame's float positions (box_scratch or this
                                // thread's buffer)
  std::atomic<bool> failed_{false};
  std::mutex box_mutex_;
  Bounds box_;
  bool have_box_ = false;
};

// Frames of this process that took SkinThenHostEncode (a value failed its encoding): for
// tests, which check that a frame they expect to pass was encoded directly.
uint64_t HostEncodedFallbacks();
void CountHostEncodedFallback();

// Skins then encodes the whole frame the host's way (float32 arrays, then ComputeBounds,
// EncodePositions, EncodeNormals, EncodeTangents in that order): the error path of a frame
// whose direct encoding failed. skin_floats(positions, normals, tangents) skins the frame
// into the given frame-sized arrays (normals / tangents null when not asked for).
template <typename SkinFloats>
Status SkinThenHostEncode(const EncodedOutput& out, std::size_t vertex_count,
                          const SkinFloats& skin_floats);

// The host encoder's sequence over float arrays (as the server's EncodeInstance).
Status HostEncode(const EncodedOutput& out, std::span<const float> positions,
                  std::span<const float> normals, std::span<const float> tangents);

// 3 * vertex_count floats of this thread, grown, never shrunk: snorm16's positions for an
// in-process caller that gives no EncodedOutput::box_scratch.
float* ThreadFloatPositions(std::size_t vertex_count);

template <typename SkinFloats>
Status SkinThenHostEncode(const EncodedOutput& out, std::size_t vertex_count,
                          const SkinFloats& skin_floats) {
  CountHostEncodedFallback();
  const bool normals = !out.normals.empty(), tangents = !out.tangents.empty();
  // This frame's only, freed on return: a client can send values the encoding refuses at
  // will, and frame-sized buffers kept on every compute thread would escape the server's
  // in-flight budget.
  AlignedBuffer<float> p(3 * vertex_count), n(normals ? 3 * vertex_count : 0),
      t(tangents ? 4 * vertex_count : 0);
  skin_floats(p.data(), normals ? n.data() : nullptr, tangents ? t.data() : nullptr);
  return HostEncode(out, p.span(), n.span(), t.span());
}

}  // namespace skinserve::simd
