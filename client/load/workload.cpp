#include "workload.h"

#include <stdexcept>

#include "skinserve/core/synthetic.h"

namespace skinserve::load {

Workload MakeWorkload(uint32_t vertices, uint32_t bones, uint32_t joints, bool normals,
                      uint64_t seed) {
  Workload w;
  w.vertices = vertices;
  w.bones = bones;
  w.joints = joints;
  w.normals = normals;
  w.arrays = std::make_shared<const MeshArrays>(MakeSyntheticMesh({.vertex_count = vertices,
                                                                   .influences = bones,
                                                                   .joint_count = joints,
                                                                   .normals = normals,
                                                                   .seed = seed}));
  auto mesh = Mesh::Create(*w.arrays);
  if (!mesh.ok()) throw std::runtime_error(mesh.status().ToString());
  w.mesh = *mesh;
  for (int f = 0; f < kDistinctPalettes; ++f) {
    w.palettes.push_back(MakeSyntheticPalette(joints, seed, f));
  }
  return w;
}

}  // namespace skinserve::load
