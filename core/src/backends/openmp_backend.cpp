// `openmp`: the serial scalar loop, its vertices split across the compute threads.
// Compiled without auto-vectorisation, like `serial`, so the speedup is the threads'.
#include "backend_factories.h"
#include "cpu_model.h"
#include "parallel_range.h"
#include "scalar_skinning.h"

namespace skinserve {
namespace {

class OpenMpBackend final : public Backend {
 public:
  explicit OpenMpBackend(int threads) {
    info_.id = "openmp";
    info_.description = "the scalar loop across threads with OpenMP";
    info_.device = CpuModelName();
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
        [&](std::size_t first, std::size_t last) { scalar::SkinScalar(mesh, frame, first, last); });
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeOpenMpBackend(int threads) {
  return std::make_unique<OpenMpBackend>(threads);
}

}  // namespace skinserve
