// `serial`: the paper's optimised scalar loop on one thread, the baseline of every speedup.
// Compiled without auto-vectorisation (core/CMakeLists.txt) so it stays scalar.
#include "backend_factories.h"
#include "cpu_model.h"
#include "scalar_skinning.h"

namespace skinserve {
namespace {

class SerialBackend final : public Backend {
 public:
  SerialBackend() {
    info_.id = "serial";
    info_.description = "scalar C++ on one thread (the baseline)";
    info_.device = CpuModelName();
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    scalar::SkinScalar(prepared.mesh(), frame, 0, prepared.mesh().vertex_count());
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeSerialBackend() { return std::make_unique<SerialBackend>(); }

}  // namespace skinserve
