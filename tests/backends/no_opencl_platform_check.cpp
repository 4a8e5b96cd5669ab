// Run by ctest with OCL_ICD_VENDORS pointing at an empty directory, so the OpenCL ICD
// loader finds no platform: the OpenCL backends must be listed unavailable with the
// reason, and every other backend must still skin correctly (but SSE off x86).
#include <cstdio>
#include <string>

#include "skinserve/engine/backend_registry.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

int main() {
  using namespace skinserve;
  int failures = 0;
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 999, .influences = 3})).value();
  const auto palette = MakeSyntheticPalette(77, 1, 2);
  for (const auto& backend : CreateAllBackends(2)) {
    const BackendInfo& info = backend->info();
    const bool opencl = info.id.rfind("opencl", 0) == 0;
    if (opencl) {
      const bool ok = !info.available &&
                      info.unavailable_reason.find("no OpenCL platform") != std::string::npos &&
                      backend->Prepare(mesh).status().code() == StatusCode::kFailedPrecondition;
      std::printf("%-16s unavailable: %s -> %s\n", info.id.c_str(), info.unavailable_reason.c_str(),
                  ok ? "ok" : "WRONG");
      failures += ok ? 0 : 1;
      continue;
    }
#if !defined(__SSE2__)
    if (info.id == "sse" || info.id == "sse-openmp") {  // x86 only: unavailable, saying why
      const bool ok = !info.available && info.unavailable_reason.find("x86") != std::string::npos;
      std::printf("%-16s unavailable off x86 -> %s\n", info.id.c_str(), ok ? "ok" : "WRONG");
      failures += ok ? 0 : 1;
      continue;
    }
#endif
    auto prepared = backend->Prepare(mesh);
    std::vector<float> positions(3 * 999);
    const bool skinned = prepared.ok() && backend->Skin(**prepared, {palette, positions, {}}).ok();
    const bool ok = info.available && skinned &&
                    (info.id == "passthrough" ||
                     CompareWithReference(*mesh, palette, positions, {}).within_tolerance());
    std::printf("%-16s available -> %s\n", info.id.c_str(), ok ? "ok" : "WRONG");
    failures += ok ? 0 : 1;
  }
  std::printf("%d failed\n", failures);
  return failures == 0 ? 0 : 1;
}
