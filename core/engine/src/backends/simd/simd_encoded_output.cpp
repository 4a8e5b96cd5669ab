#include "backends/simd/simd_encoded_output.h"

#include "backends/common/parallel_range.h"

namespace skinserve::simd {

std::vector<VertexEncoding> EncodedOutputs() {
  return {VertexEncoding::kFloat16, VertexEncoding::kSnorm16};
}

namespace {

std::atomic<uint64_t> host_encoded_fallbacks{0};

AlignedBuffer<float>& Grown(AlignedBuffer<float>& buffer, std::size_t floats) {
  if (buffer.size() < floats) buffer = AlignedBuffer<float>(floats);
  return buffer;
}

std::span<std::byte> Slice(std::span<std::byte> bytes, std::size_t values_per_vertex,
                           std::size_t first, std::size_t count, std::size_t bytes_per_value) {
  return bytes.subspan(first * values_per_vertex * bytes_per_value,
                       count * values_per_vertex * bytes_per_value);
}

}  // namespace

uint64_t HostEncodedFallbacks() { return host_encoded_fallbacks.load(); }
void CountHostEncodedFallback() { host_encoded_fallbacks.fetch_add(1); }

float* ThreadFloatPositions(std::size_t vertex_count) {
  thread_local AlignedBuffer<float> positions;
  return Grown(positions, 3 * vertex_count).data();
}

EncodedWriter::EncodedWriter(const EncodedOutput& out, std::size_t vertex_count)
    : out_(out),
      vertex_count_(vertex_count),
      boxed_(QuantizedToBox(out.encoding)),
      wants_normals_(!out.normals.empty()),
      wants_tangents_(!out.tangents.empty()) {
  if (boxed_) {
    positions_ = out.box_scratch.size() >= 3 * vertex_count ? out.box_scratch.data()
                                                            : ThreadFloatPositions(vertex_count);
  }
}

float* EncodedWriter::ThreadScratch() {
  thread_local AlignedBuffer<float> scratch(10 * kChunkVertices);
  return scratch.data();
}

bool EncodedWriter::EncodeChunk(std::size_t first, std::size_t count, const float* p,
                                const float* n, const float* t) const {
  const std::size_t value_bytes = EncodedBytesPerValue(out_.encoding);
  if (boxed_) {
    // Positions stay floats until Finish has the frame's box.
  } else if (!EncodePositions(out_.encoding, {p, 3 * count}, Bounds{},
                              Slice(out_.positions, 3, first, count, value_bytes), first)
                  .ok()) {
    return false;
  }
  if (n != nullptr && !EncodeNormals(out_.encoding, {n, 3 * count},
                                     Slice(out_.normals, 3, first, count, value_bytes), first)
                           .ok()) {
    return false;
  }
  if (t != nullptr && !EncodeTangents(out_.encoding, {t, 4 * count},
                                      Slice(out_.tangents, 4, first, count, value_bytes), first)
                           .ok()) {
    return false;
  }
  return true;
}

void EncodedWriter::BoxRange(std::size_t from, std::size_t to) {
  // One pass per range, as the host encoder's; a box per chunk measured slower.
  Result<Bounds> box = ComputeBounds({positions_ + 3 * from, 3 * (to - from)}, from);
  if (!box.ok()) {
    failed_.store(true, std::memory_order_relaxed);
    return;
  }
  std::lock_guard lock(box_mutex_);
  if (!have_box_) {
    box_ = *box;
    have_box_ = true;
    return;
  }
  for (int a = 0; a < 3; ++a) {
    box_.min[a] = std::min(box_.min[a], box->min[a]);
    box_.max[a] = std::max(box_.max[a], box->max[a]);
  }
}

bool EncodedWriter::Finish(int threads) {
  if (failed_.load()) return false;
  if (!boxed_) return true;
  const Bounds box = have_box_ ? box_ : Bounds{};  // no vertices: ComputeBounds' zero box
  *out_.bounds = box;
  const std::size_t value_bytes = EncodedBytesPerValue(out_.encoding);
  const auto encode = [&](std::size_t first, std::size_t last) {
    if (!EncodePositions(out_.encoding, {positions_ + 3 * first, 3 * (last - first)}, box,
                         Slice(out_.positions, 3, first, last - first, value_bytes), first)
             .ok()) {
      failed_.store(true, std::memory_order_relaxed);
    }
  };
  if (threads <= 1) {
    encode(0, vertex_count_);
  } else {
    ParallelOverVertices(vertex_count_, threads, encode);
  }
  return !failed_.load();
}

Status HostEncode(const EncodedOutput& out, std::span<const float> positions,
                  std::span<const float> normals, std::span<const float> tangents) {
  Bounds box;
  if (QuantizedToBox(out.encoding)) {
    Result<Bounds> computed = ComputeBounds(positions);
    if (!computed.ok()) return computed.status();
    box = *computed;
    *out.bounds = box;
  }
  if (Status s = EncodePositions(out.encoding, positions, box, out.positions); !s.ok()) return s;
  if (!normals.empty()) {
    if (Status s = EncodeNormals(out.encoding, normals, out.normals); !s.ok()) return s;
  }
  if (!tangents.empty()) {
    if (Status s = EncodeTangents(out.encoding, tangents, out.tangents); !s.ok()) return s;
  }
  return Status::Ok();
}

}  // namespace skinserve::simd
