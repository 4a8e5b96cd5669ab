#include "backend_fixture.h"

#include <limits>

#include "skinserve/engine/backend_registry.h"

namespace skinserve::testing {

const std::vector<std::unique_ptr<Backend>>& AllBackends() {
  static const auto* backends = new std::vector<std::unique_ptr<Backend>>(CreateAllBackends(2));
  return *backends;
}

Backend& BackendById(const std::string& id) {
  for (const auto& backend : AllBackends()) {
    if (backend->info().id == id) return *backend;
  }
  ADD_FAILURE() << "no backend " << id;
  std::abort();
}

std::vector<std::string> ComputingBackendIds() {
  std::vector<std::string> ids;
  for (const auto& backend : AllBackends()) {
    const std::string& id = backend->info().id;
    if (id != "passthrough" && (kSseBackendsRunHere || !IsSseBackend(id))) ids.push_back(id);
  }
  return ids;
}

std::vector<std::string> BackendIdsWithMethod(SkinningMethod method) {
  std::vector<std::string> ids;
  for (const auto& backend : AllBackends()) {
    if (backend->info().Supports(method)) ids.push_back(backend->info().id);
  }
  return ids;
}

Output SkinOnce(Backend& backend, const PreparedMesh& prepared, std::span<const float> palette,
                bool with_normals, SkinningMethod method) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const std::size_t n = 3ull * prepared.mesh().vertex_count();
  Output out{std::vector<float>(n, kNaN), std::vector<float>(with_normals ? n : 0, kNaN)};
  const SkinFrame frame{
      .palette = palette, .positions = out.positions, .normals = out.normals, .method = method};
  Status valid = frame.Validate(prepared.mesh());
  EXPECT_TRUE(valid.ok()) << valid.ToString();
  Status skinned = backend.Skin(prepared, frame);
  EXPECT_TRUE(skinned.ok()) << skinned.ToString();
  return out;
}

}  // namespace skinserve::testing
