// `simd` and `simd-openmp`: the Highway kernel (simd_kernel.cpp) at the best SIMD target
// of this CPU, on one thread or split across the compute threads like `sse-openmp`.
#include <algorithm>
#include <cstdlib>
#include <new>

#include "backend_factories.h"
#include "cpu_model.h"
#include "dual_quaternion_palette.h"
#include "morph_stage.h"
#include "parallel_range.h"
#include "simd_stream.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/model/aligned_buffer.h"
#include "unavailable_backend.h"

namespace skinserve {
namespace {

// The mesh in the kernel's stream (simd_stream.h): positions, normals and tangents are the
// mesh's
// own arrays; joints (8-bit when they fit) and the first B - 1 weights are copies.
class SimdPreparedMesh final : public PreparedMesh {
 public:
  explicit SimdPreparedMesh(std::shared_ptr<const Mesh> mesh) : PreparedMesh(std::move(mesh)) {
    const Mesh& m = this->mesh();
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

 private:
  AlignedBuffer<uint8_t> joints8_;
  AlignedBuffer<float> weights_;
  simd::VertexStream stream_;
};

// The frame's palette as the kernel reads it: per joint the four columns of the 3x4
// matrix, each padded with a zero (simd_stream.h). Built in this thread's buffer, grown
// and never shrunk, like sse::ColumnPalette.
const float* ColumnPalette(std::span<const float> palette) {
  thread_local AlignedBuffer<float> buffer;
  const std::size_t joints = palette.size() / 12;
  if (buffer.size() < joints * simd::kFloatsPerJoint) {
    buffer = AlignedBuffer<float>(joints * simd::kFloatsPerJoint);
  }
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

// The frame's quaternion sign table (simd::DualQuaternionFrame::signs), in this thread's
// buffer like ColumnPalette: J x J dot products, built only where they are fewer than the
// vertices' own (a vertex compares each of its B - 1 other influences with its first) and
// the joints stream as 8 bits (J <= 256, 256 KB at most). Null otherwise.
const float* SignTable(const DualQuaternionPalette& quaternions, const Mesh& mesh,
                       const simd::VertexStream& stream) {
  const std::size_t joints = mesh.joint_count();
  const std::size_t dots = std::size_t{mesh.vertex_count()} * (mesh.influences() - 1);
  if (stream.joints8 == nullptr || joints * joints > dots) return nullptr;
  thread_local AlignedBuffer<float> buffer;
  if (buffer.size() < joints * joints) buffer = AlignedBuffer<float>(joints * joints);
  for (std::size_t i = 0; i < joints; ++i) {
    const float* a = quaternions.joint(i);
    for (std::size_t j = 0; j < joints; ++j) {
      const float* b = quaternions.joint(j);
      const float dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
      buffer[i * joints + j] = dot < 0 ? -1.0f : 1.0f;
    }
  }
  return buffer.data();
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
    const auto& stream = static_cast<const SimdPreparedMesh&>(prepared).stream();
    const Outputs out{.normals = frame.normals.empty() ? nullptr : frame.normals.data(),
                      .tangents = frame.tangents.empty() ? nullptr : frame.tangents.data()};
    try {
      if (frame.method == SkinningMethod::kDualQuaternion) {
        const DualQuaternionPalette quaternions(frame.palette);
        const simd::DualQuaternionFrame palette{
            .quaternions = quaternions.joint(0),
            .signs = SignTable(quaternions, prepared.mesh(), stream),
            .joint_count = prepared.mesh().joint_count()};
        Run(kernel_.skin_dual_quaternion_range, prepared.mesh(), stream, palette, frame, out);
      } else {
        const float* columns = ColumnPalette(frame.palette);
        Run(kernel_.skin_range, prepared.mesh(), stream, columns, frame, out);
      }
    } catch (const std::bad_alloc&) {  // a palette or morph scratch larger than any seen so far
      return ResourceExhausted(info_.id +
                               ": out of memory for the frame's palette or morph scratch");
    }
    return Status::Ok();
  }

 private:
  struct Outputs {
    float* normals = nullptr;   // null: no normals
    float* tangents = nullptr;  // null: no tangents
  };

  // Runs `range` (a linear or dual-quaternion kernel) over the frame's vertices, on the
  // calling thread or split across the frame's threads, each range from the rest arrays
  // the morph stage hands it (morph_stage.h).
  template <typename RangeFn, typename Palette>
  void Run(RangeFn range, const Mesh& mesh, const simd::VertexStream& stream,
           const Palette& palette, const SkinFrame& frame, const Outputs& out) {
    const std::size_t count = mesh.vertex_count();
    const auto skin_range = [&](std::size_t first, std::size_t last) {
      ForEachMorphedRange(mesh, frame, first, last,
                          [&](const float* rest_p, const float* rest_n, const float* rest_t,
                              std::size_t from, std::size_t to) {
                            simd::VertexStream morphed = stream;
                            morphed.positions = rest_p;
                            if (rest_n != nullptr) morphed.normals = rest_n;
                            if (rest_t != nullptr) morphed.tangents = rest_t;
                            range(morphed, palette, frame.positions.data(), out.normals,
                                  out.tangents, from, to);
                          });
    };
    const int threads = FrameThreads(frame.threads, info_.threads);
    if (threads <= 1) {
      skin_range(0, count);
    } else {
      ParallelOverVertices(count, threads, skin_range);
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
                   .tangents = true};
  simd::Kernel kernel;
  std::string error;
  if (!simd::SelectKernel(max_target, &kernel, &error)) {
    info.unavailable_reason = error;
    return std::make_unique<UnavailableBackend>(std::move(info));
  }
  info.simd_target = kernel.target;
  info.simd_width = kernel.lanes;
  return std::make_unique<SimdBackend>(std::move(info), kernel);
}

std::unique_ptr<Backend> MakeSimdBackend(int threads) {
  const char* cap = std::getenv(kSimdMaxTargetVariable);
  return CreateSimdBackend(threads, cap == nullptr ? "" : cap);
}

}  // namespace skinserve
