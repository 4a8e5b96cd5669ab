// `simd` and `simd-openmp`: the Highway kernel (simd_kernel.cpp) at the best SIMD target
// of this CPU, on one thread or split across the compute threads like `sse-openmp`.
#include <algorithm>
#include <cstdlib>
#include <new>

#include "backend_factories.h"
#include "cpu_model.h"
#include "morph_stage.h"
#include "parallel_range.h"
#include "simd_stream.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/model/aligned_buffer.h"
#include "unavailable_backend.h"

namespace skinserve {
namespace {

// The mesh in the kernel's stream (simd_stream.h): positions and normals are the mesh's
// own arrays; joints (8-bit when they fit) and the first B - 1 weights are copies.
class SimdPreparedMesh final : public PreparedMesh {
 public:
  explicit SimdPreparedMesh(std::shared_ptr<const Mesh> mesh) : PreparedMesh(std::move(mesh)) {
    const Mesh& m = this->mesh();
    const uint32_t b = m.influences();
    stream_.influences = b;
    stream_.positions = m.positions().data();
    stream_.normals = m.has_normals() ? m.normals().data() : nullptr;
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

class SimdBackend final : public Backend {
 public:
  SimdBackend(BackendInfo info, simd::Kernel kernel) : info_(std::move(info)), kernel_(kernel) {}
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
    const std::size_t count = prepared.mesh().vertex_count();
    float* out_n = frame.normals.empty() ? nullptr : frame.normals.data();
    try {
      const float* columns = ColumnPalette(frame.palette);
      const int threads = FrameThreads(frame.threads, info_.threads);
      // The kernel skins each range from the rest arrays the morph stage hands it.
      const auto skin_range = [&](std::size_t first, std::size_t last) {
        ForEachMorphedRange(
            prepared.mesh(), frame, first, last,
            [&](const float* rest_p, const float* rest_n, std::size_t from, std::size_t to) {
              simd::VertexStream morphed = stream;
              morphed.positions = rest_p;
              if (rest_n != nullptr) morphed.normals = rest_n;
              kernel_.skin_range(morphed, columns, frame.positions.data(), out_n, from, to);
            });
      };
      if (threads <= 1) {
        skin_range(0, count);
      } else {
        ParallelOverVertices(count, threads, skin_range);
      }
    } catch (const std::bad_alloc&) {  // a palette or morph scratch larger than any seen so far
      return ResourceExhausted(info_.id +
                               ": out of memory for the frame's palette or morph scratch");
    }
    return Status::Ok();
  }

 private:
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
                   .min_threads = 1,        // a parallel loop runs on as few threads as given
                   .morph_targets = true};  // the morph stage feeds the kernel
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
