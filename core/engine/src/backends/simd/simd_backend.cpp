// `simd` and `simd-openmp`: the Highway kernel (simd_kernel.cpp) at the best SIMD target
// of this CPU, on one thread or split across the compute threads like `sse-openmp`.
#include <algorithm>
#include <cstdlib>
#include <new>
#include <optional>

#include "backends/common/backend_factories.h"
#include "backends/common/cpu_model.h"
#include "backends/common/dual_quaternion_palette.h"
#include "backends/common/morph_stage.h"
#include "backends/common/parallel_range.h"
#include "backends/common/quantized_palette.h"
#include "backends/common/unavailable_backend.h"
#include "backends/simd/simd_encoded_output.h"
#include "backends/simd/simd_stream.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/model/aligned_buffer.h"

namespace skinserve {
namespace {

// The mesh in the kernel's stream (simd_stream.h): positions, normals and tangents are the
// mesh's own arrays; joints (8-bit when they fit) and the first B - 1 weights are copies. A
// mesh with a quantized rest stream is read in place, nothing copied.
class SimdPreparedMesh final : public PreparedMesh {
 public:
  explicit SimdPreparedMesh(std::shared_ptr<const Mesh> mesh) : PreparedMesh(std::move(mesh)) {
    const Mesh& m = this->mesh();
    if (const QuantizedRest* q = m.quantized_rest()) {
      quantized_ = simd::QuantizedStream{
          .influences = m.influences(),
          .positions = q->positions.data(),
          .normals = q->normals.empty() ? nullptr : q->normals.data(),
          .tangents = q->tangents.empty() ? nullptr : q->tangents.data(),
          .joints8 = q->joints8.empty() ? nullptr : q->joints8.data(),
          .joints16 = q->joints16.empty() ? nullptr : q->joints16.data(),
          .weights8 = q->weights8.empty() ? nullptr : q->weights8.data(),
          .weights16 = q->weights16.empty() ? nullptr : q->weights16.data(),
          .normal_scale = {1.0f / q->scale[0], 1.0f / q->scale[1], 1.0f / q->scale[2]}};
      return;
    }
    const uint32_t b = m.influences();
    stream_.influences = b;
    stream_.positions = m.positions().data();
    stream_.normals = m.has_normals() ? m.normals().data() : nullptr;
    stream_.tangents = m.has_tangents() ? m.tangents().data() : nullptr;
    if (m.joint_count() <= 256) {
      joints8_ = AlignedBuffer<uint8_t>(m.joints().size());
      for (std::size_t i = 0; i < m.joints().size(); ++i) {
        joints8_[i] = static_cast<uint8_t>(m.joints()[i]);
      }
      stream_.joints8 = joints8_.data();
    } else {
      stream_.joints16 = m.joints().data();
    }
    if (b > 1) {
      weights_ = AlignedBuffer<float>(std::size_t{m.vertex_count()} * (b - 1));
      for (std::size_t v = 0; v < m.vertex_count(); ++v) {
        for (uint32_t i = 0; i + 1 < b; ++i) weights_[v * (b - 1) + i] = m.weights()[v * b + i];
      }
      stream_.weights = weights_.data();
    }
  }
  const simd::VertexStream& stream() const { return stream_; }
  // Null for a float mesh.
  const simd::QuantizedStream* quantized() const { return quantized_ ? &*quantized_ : nullptr; }

 private:
  std::optional<simd::QuantizedStream> quantized_;
  AlignedBuffer<uint8_t> joints8_;
  AlignedBuffer<float> weights_;
  simd::VertexStream stream_;
};

// The frame's palette as the kernel reads it: per joint the four columns of the 3x4
// matrix, each padded with a zero (simd_stream.h). Built in this thread's buffer, grown
// and never shrunk, like sse::ColumnPalette.
// This thread's column buffer, at least `joints` records long: grown, never shrunk.
AlignedBuffer<float>& ThreadColumnBuffer(std::size_t joints) {
  thread_local AlignedBuffer<float> buffer;
  if (buffer.size() < joints * simd::kFloatsPerJoint) {
    buffer = AlignedBuffer<float>(joints * simd::kFloatsPerJoint);
  }
  return buffer;
}

const float* ColumnPalette(std::span<const float> palette) {
  const std::size_t joints = palette.size() / 12;
  AlignedBuffer<float>& buffer = ThreadColumnBuffer(joints);
  for (std::size_t j = 0; j < joints; ++j) {
    const float* rows = palette.data() + 12 * j;
    float* out = buffer.data() + simd::kFloatsPerJoint * j;
    for (int c = 0; c < 4; ++c) {
      out[4 * c] = rows[c], out[4 * c + 1] = rows[4 + c], out[4 * c + 2] = rows[8 + c];
      out[4 * c + 3] = 0.0f;
    }
  }
  return buffer.data();
}

// The same for a quantized rest stream: each joint's matrix folded with the box
// (quantized_palette.h), so the loop multiplies the integers directly.
const float* QuantizedColumnPalette(std::span<const float> palette, const QuantizedRest& rest) {
  const std::size_t joints = palette.size() / 12;
  AlignedBuffer<float>& buffer = ThreadColumnBuffer(joints);
  for (std::size_t j = 0; j < joints; ++j) {
    float rows[12];
    FoldQuantizedBox(palette.data() + 12 * j, rest, rows);
    float* out = buffer.data() + simd::kFloatsPerJoint * j;
    for (int c = 0; c < 4; ++c) {
      out[4 * c] = rows[c], out[4 * c + 1] = rows[4 + c], out[4 * c + 2] = rows[8 + c];
      out[4 * c + 3] = 0.0f;
    }
  }
  return buffer.data();
}

// The frame's dual quaternions for the kernel (simd::DualQuaternionFrame), with the
// hemisphere table where it is cheaper than a dot product per vertex and influence (a
// vertex compares each of its B - 1 other influences with its first; the table costs J x J)
// and the joints stream as 8 bits (J <= 256: 128 KB of table at most). The table and the
// palette doubled with its negation live in this thread's buffers, like ColumnPalette.
simd::DualQuaternionFrame KernelPalette(const DualQuaternionPalette& quaternions, const Mesh& mesh,
                                        const simd::VertexStream& stream) {
  constexpr std::size_t kStride = DualQuaternionPalette::kFloatsPerJoint;
  const std::size_t joints = mesh.joint_count();
  simd::DualQuaternionFrame frame{.quaternions = quaternions.joint(0),
                                  .joint_count = mesh.joint_count()};
  const std::size_t dots = std::size_t{mesh.vertex_count()} * (mesh.influences() - 1);
  if (stream.joints8 == nullptr || joints * joints > dots) return frame;
  thread_local AlignedBuffer<float> both;
  thread_local AlignedBuffer<uint16_t> table;
  if (both.size() < 2 * kStride * joints) both = AlignedBuffer<float>(2 * kStride * joints);
  if (table.size() < joints * joints) table = AlignedBuffer<uint16_t>(joints * joints);
  for (std::size_t j = 0; j < joints; ++j) {
    const float* q = quaternions.joint(j);
    for (std::size_t e = 0; e < kStride; ++e) {
      both[kStride * j + e] = q[e];
      both[kStride * (joints + j) + e] = -q[e];
    }
  }
  for (std::size_t i = 0; i < joints; ++i) {
    const float* a = quaternions.joint(i);
    for (std::size_t j = 0; j < joints; ++j) {
      const float* b = quaternions.joint(j);
      // The dot product the kernel's per-vertex path takes (q_i . q_i = 1: its own record).
      const float dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
      table[i * joints + j] = static_cast<uint16_t>(kStride * (dot < 0 ? joints + j : j));
    }
  }
  frame.quaternions = both.data();
  frame.hemisphere = table.data();
  return frame;
}

class SimdBackend final : public Backend {
 public:
  SimdBackend(BackendInfo info, simd::Kernel kernel) : info_(std::move(info)), kernel_(kernel) {
    info_.methods = {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion};
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    try {
      return std::unique_ptr<PreparedMesh>(std::make_unique<SimdPreparedMesh>(std::move(mesh)));
    } catch (const std::bad_alloc&) {
      return ResourceExhausted(info_.id + ": out of memory for the mesh's vertex stream");
    }
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    const auto& simd_mesh = static_cast<const SimdPreparedMesh&>(prepared);
    try {
      if (frame.encoded.active()) return SkinEncoded(simd_mesh, frame);
      FloatSink sink{.positions = frame.positions.data(),
                     .normals = frame.normals.empty() ? nullptr : frame.normals.data(),
                     .tangents = frame.tangents.empty() ? nullptr : frame.tangents.data()};
      return Dispatch(simd_mesh, frame, sink);
    } catch (const std::bad_alloc&) {  // a palette or morph scratch larger than any seen so far
      return ResourceExhausted(info_.id +
                               ": out of memory for the frame's palette or morph scratch");
    }
  }

 private:
  // Where the loop writes float32 output: the frame's own arrays (or the error path's).
  struct FloatSink {
    float* positions = nullptr;
    float* normals = nullptr;   // null: no normals
    float* tangents = nullptr;  // null: no tangents
    // skin(offset, count, p, n, t) as simd::EncodedWriter::Write: here in place.
    template <typename Skin>
    void Write(std::size_t from, std::size_t to, const Skin& skin) const {
      skin(0, to - from, positions + 3 * from, normals == nullptr ? nullptr : normals + 3 * from,
           tangents == nullptr ? nullptr : tangents + 4 * from);
    }
  };

  // Encoded output (simd_encoded_output.h): chunks encoded while hot; a value that fails its
  // encoding sends the frame through float32 and the host encoder, for its error.
  Status SkinEncoded(const SimdPreparedMesh& mesh, const SkinFrame& frame) {
    const std::size_t count = mesh.mesh().vertex_count();
    simd::EncodedWriter writer(frame.encoded, count);
    if (Status s = Dispatch(mesh, frame, writer); !s.ok()) return s;
    if (writer.Finish(FrameThreads(frame.threads, info_.threads))) return Status::Ok();
    Status skinned = Status::Ok();
    Status encoded =
        simd::SkinThenHostEncode(frame.encoded, count, [&](float* p, float* n, float* t) {
          FloatSink sink{.positions = p, .normals = n, .tangents = t};
          skinned = Dispatch(mesh, frame, sink);
        });
    return skinned.ok() ? encoded : skinned;
  }

  // The frame's palette for its method and mesh, then the loop into `sink` (FloatSink or
  // simd::EncodedWriter).
  template <typename Sink>
  Status Dispatch(const SimdPreparedMesh& simd_mesh, const SkinFrame& frame, Sink& sink) {
    const Mesh& mesh = simd_mesh.mesh();
    if (const simd::QuantizedStream* quantized = simd_mesh.quantized()) {
      if (frame.method != SkinningMethod::kLinear) {
        return FailedPrecondition(
            info_.id + ": mesh " + mesh.id() +
            " is stored with a quantized rest stream, which this backend skins with the "
            "linear method only; skin it linear, or on a backend that reads the float values "
            "it decodes to (serial, sse, ...), or upload it as float32");
      }
      const float* columns = QuantizedColumnPalette(frame.palette, *mesh.quantized_rest());
      RunQuantized(*quantized, mesh, columns, frame, sink);
    } else if (frame.method == SkinningMethod::kDualQuaternion) {
      const DualQuaternionPalette quaternions(frame.palette);
      const simd::DualQuaternionFrame palette =
          KernelPalette(quaternions, mesh, simd_mesh.stream());
      Run(kernel_.skin_dual_quaternion_range, mesh, simd_mesh.stream(), palette, frame, sink);
    } else {
      const float* columns = ColumnPalette(frame.palette);
      Run(kernel_.skin_range, mesh, simd_mesh.stream(), columns, frame, sink);
    }
    return Status::Ok();
  }

  // Runs `range` (a linear or dual-quaternion kernel) over the frame's vertices, on the
  // calling thread or split across the frame's threads, each range from the rest arrays
  // the morph stage hands it (morph_stage.h), into `sink`.
  template <typename RangeFn, typename Palette, typename Sink>
  void Run(RangeFn range, const Mesh& mesh, const simd::VertexStream& stream,
           const Palette& palette, const SkinFrame& frame, Sink& sink) {
    const std::size_t count = mesh.vertex_count();
    const auto skin_range = [&](std::size_t first, std::size_t last) {
      ForEachMorphedRange(
          mesh, frame, first, last, [&](const RestArrays& rest, std::size_t from, std::size_t to) {
            sink.Write(from, to,
                       [&](std::size_t offset, std::size_t n, float* p, float* nrm, float* tan) {
                         // Every array of the stream from vertex `v` on, so the kernel reads
                         // a morphed chunk's scratch from its index 0.
                         const std::size_t v = from + offset;
                         const std::size_t skip = v - rest.first;
                         const std::size_t b = stream.influences;
                         simd::VertexStream chunk = stream;
                         chunk.positions = rest.positions + 3 * skip;
                         chunk.normals = rest.normals ? rest.normals + 3 * skip : nullptr;
                         chunk.tangents = rest.tangents ? rest.tangents + 4 * skip : nullptr;
                         if (chunk.joints8 != nullptr) chunk.joints8 += b * v;
                         if (chunk.joints16 != nullptr) chunk.joints16 += b * v;
                         if (chunk.weights != nullptr) chunk.weights += (b - 1) * v;
                         range(chunk, palette, p, nrm, tan, 0, n);
                       });
          });
    };
    const int threads = FrameThreads(frame.threads, info_.threads);
    if (threads <= 1) {
      skin_range(0, count);
    } else {
      ParallelOverVertices(count, threads, skin_range);
    }
  }

  // The same over a quantized rest stream (no morph targets: CheckRestEncoding).
  template <typename Sink>
  void RunQuantized(const simd::QuantizedStream& stream, const Mesh& mesh, const float* columns,
                    const SkinFrame& frame, Sink& sink) {
    const auto skin_range = [&](std::size_t first, std::size_t last) {
      sink.Write(first, last,
                 [&](std::size_t offset, std::size_t n, float* p, float* nrm, float* tan) {
                   const std::size_t v = first + offset;
                   const std::size_t b = stream.influences;
                   simd::QuantizedStream chunk = stream;
                   chunk.positions += 3 * v;
                   if (chunk.normals != nullptr) chunk.normals += 3 * v;
                   if (chunk.tangents != nullptr) chunk.tangents += 4 * v;
                   if (chunk.joints8 != nullptr) chunk.joints8 += b * v;
                   if (chunk.joints16 != nullptr) chunk.joints16 += b * v;
                   if (chunk.weights8 != nullptr) chunk.weights8 += (b - 1) * v;
                   if (chunk.weights16 != nullptr) chunk.weights16 += (b - 1) * v;
                   kernel_.skin_quantized_range(chunk, columns, p, nrm, tan, 0, n);
                 });
    };
    const int threads = FrameThreads(frame.threads, info_.threads);
    if (threads <= 1) {
      skin_range(0, mesh.vertex_count());
    } else {
      ParallelOverVertices(mesh.vertex_count(), threads, skin_range);
    }
  }

  BackendInfo info_;
  simd::Kernel kernel_;
};

}  // namespace

std::vector<std::string> RunnableSimdTargets() { return simd::RunnableTargets(); }

Status CapSimdDispatch(const std::string& max_target) {
  std::string error;
  if (!simd::CapDispatch(max_target, &error)) return InvalidArgument(error);
  return Status::Ok();
}

std::unique_ptr<Backend> CreateSimdBackend(int threads, const std::string& max_target) {
  BackendInfo info{.id = threads <= 0 ? "simd" : "simd-openmp",
                   .description = threads <= 0
                                      ? "Highway at the CPU's best SIMD target on one thread"
                                      : "the Highway loop across threads with OpenMP",
                   .device = CpuModelName(),
                   .threads = std::max(threads, 1),
                   .min_threads = 1,       // a parallel loop runs on as few threads as given
                   .morph_targets = true,  // the morph stage feeds the kernel
                   .tangents = true,
                   .quantized_rest = true};
  simd::Kernel kernel;
  std::string error;
  if (!simd::SelectKernel(max_target, &kernel, &error)) {
    info.unavailable_reason = error;
    return std::make_unique<UnavailableBackend>(std::move(info));
  }
  info.encoded_outputs = simd::EncodedOutputs();
  info.encoded_box_scratch = true;  // snorm16's float positions (simd_encoded_output.h)
  info.simd_target = kernel.target;
  info.simd_width = kernel.lanes;
  return std::make_unique<SimdBackend>(std::move(info), kernel);
}

std::unique_ptr<Backend> MakeSimdBackend(int threads) {
  const char* cap = std::getenv(kSimdMaxTargetVariable);
  return CreateSimdBackend(threads, cap == nullptr ? "" : cap);
}

}  // namespace skinserve
