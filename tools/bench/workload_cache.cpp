#include "workload_cache.h"

#include <algorithm>
#include <stdexcept>

#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::bench {

const Workload& WorkloadCache::Get(uint32_t vertices, uint32_t bones, bool morph, RestEncoding rest,
                                   uint32_t copy) {
  std::lock_guard lock(mutex_);
  auto [it, inserted] = workloads_.try_emplace({vertices, bones, morph, rest, copy});
  if (inserted) {
    // Copies differ in the seed's high bits, clear of every (vertices, bones) pair's.
    const uint64_t seed = vertices * 10ull + bones + (static_cast<uint64_t>(copy) << 40);
    MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                           .influences = bones,
                                           .joint_count = kPaperJoints,
                                           .normals = true,
                                           // (read only by BM_SkinTangents*)
                                           .tangents = true,
                                           .seed = seed,
                                           .sorted_by_joints = sorted_by_joints_});
    if (morph) {
      AddSyntheticMorphTargets({.targets = kMorphTargets, .fraction = kMorphFraction, .seed = seed},
                               &arrays);
    }
    // The server's vertex limit guards uploads; the bench may go past it (past a large L3).
    MeshLimits limits;
    limits.max_vertices = std::max(limits.max_vertices, vertices);
    auto mesh = Mesh::Create(arrays, {.limits = limits, .rest_encoding = rest});
    if (!mesh.ok()) throw std::runtime_error(mesh.status().ToString());
    it->second.mesh = *mesh;
    for (int frame = 0; frame < kPalettesPerWorkload; ++frame) {
      it->second.palettes.push_back(MakeSyntheticPalette(kPaperJoints, 42, frame));
      it->second.rigid_palettes.push_back(MakeRigidPalette(kPaperJoints, 42, frame));
    }
  }
  return it->second;
}

const PreparedMesh& WorkloadCache::Prepared(Backend& backend, uint32_t vertices, uint32_t bones,
                                            bool morph, RestEncoding rest, uint32_t copy) {
  const Workload& workload = Get(vertices, bones, morph, rest, copy);
  std::lock_guard lock(mutex_);
  auto& slot = prepared_[{&backend, vertices, bones, morph, rest, copy}];
  if (!slot) {
    auto prepared = backend.Prepare(workload.mesh);
    if (!prepared.ok()) throw std::runtime_error(prepared.status().ToString());
    slot = std::move(prepared).value();
  }
  return *slot;
}

}  // namespace skinserve::bench
