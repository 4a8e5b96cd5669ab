// `sse-openmp`: the SSE loop, its vertices split across the compute threads.
#include "backend_factories.h"
#include "cpu_model.h"
#include "parallel_range.h"
#include "sse_skinning.h"

namespace skinserve {
namespace {

class SseOpenMpBackend final : public Backend {
 public:
  explicit SseOpenMpBackend(int threads) {
    info_.id = "sse-openmp";
    info_.description = "the SSE loop across threads with OpenMP";
    info_.device = CpuModelName();
    info_.simd_width = 4;
    info_.threads = threads;
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    const Mesh& mesh = prepared.mesh();
    ParallelOverVertices(
        mesh.vertex_count(), info_.threads,
        [&](std::size_t first, std::size_t last) { sse::SkinSse(mesh, frame, first, last); });
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeSseOpenMpBackend(int threads) {
  return std::make_unique<SseOpenMpBackend>(threads);
}

}  // namespace skinserve
