// CpuBackend: a backend made of one skinning loop over a vertex range, run on the calling
// thread (info.threads == 1) or split across info.threads OpenMP threads. The four CPU
// backends differ only in the loop and the description.
#pragma once

#include "parallel_range.h"
#include "skinserve/core/backend.h"

namespace skinserve {

// SkinRange: void(const Mesh&, const SkinFrame&, std::size_t first, std::size_t last).
template <auto SkinRange>
class CpuBackend final : public Backend {
 public:
  explicit CpuBackend(BackendInfo info) : info_(std::move(info)) {}
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));  // skins the Mesh's own layout
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    const Mesh& mesh = prepared.mesh();
    if (info_.threads <= 1) {
      SkinRange(mesh, frame, 0, mesh.vertex_count());
    } else {
      ParallelOverVertices(
          mesh.vertex_count(), info_.threads,
          [&](std::size_t first, std::size_t last) { SkinRange(mesh, frame, first, last); });
    }
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace skinserve
