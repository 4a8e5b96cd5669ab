// `sse`: the SSE loop on one thread.
#include "backend_factories.h"
#include "cpu_model.h"
#include "sse_skinning.h"

namespace skinserve {
namespace {

class SseBackend final : public Backend {
 public:
  SseBackend() {
    info_.id = "sse";
    info_.description = "SSE intrinsics on one thread (a matrix row per register)";
    info_.device = CpuModelName();
    info_.simd_width = 4;
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    sse::SkinSse(prepared.mesh(), frame, 0, prepared.mesh().vertex_count());
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeSseBackend() { return std::make_unique<SseBackend>(); }

}  // namespace skinserve
