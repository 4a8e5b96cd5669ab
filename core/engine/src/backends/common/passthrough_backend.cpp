// `passthrough`: no compute, the rest pose straight back: the transport ceiling that load
// tests compare the real backends with.
#include <algorithm>

#include "backends/common/backend_factories.h"

namespace skinserve {
namespace {

class PassthroughBackend final : public Backend {
 public:
  PassthroughBackend() {
    info_.id = "passthrough";
    info_.description = "no compute: returns the rest pose (transport ceiling)";
    info_.device = "none";
    info_.tangents = true;  // the rest tangents, like the rest normals
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    if (Status s = CheckMorphSupport(info(), frame.morph_weights); !s.ok()) return s;
    const Mesh& mesh = prepared.mesh();
    std::copy(mesh.positions().begin(), mesh.positions().end(), frame.positions.begin());
    if (!frame.normals.empty()) {
      std::copy(mesh.normals().begin(), mesh.normals().end(), frame.normals.begin());
    }
    if (!frame.tangents.empty()) {
      std::copy(mesh.tangents().begin(), mesh.tangents().end(), frame.tangents.begin());
    }
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakePassthroughBackend() { return std::make_unique<PassthroughBackend>(); }

}  // namespace skinserve
