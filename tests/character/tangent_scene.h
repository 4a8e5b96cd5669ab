// A small skinned glTF with tangents, written by the test itself (no file on disk), and
// what it holds as the spec decodes it, in float64, kept beside it so that tests check the
// importer against what was written, never against the importer's own output.
//   primitive 0  5 vertices, float NORMAL and TANGENT (xyz lengths 1 +- up to 0.0099, w
//                0.9995 / -0.995 among exact +-1), two morph targets: target 0 with float
//                POSITION, NORMAL and TANGENT deltas, target 1 with float POSITION and
//                KHR_mesh_quantization normalized SHORT TANGENT deltas (no NORMAL); two
//                vertices move in neither
//   primitive 1  3 vertices, normalized SHORT NORMAL and TANGENT (KHR_mesh_quantization),
//                the TANGENT accessor sparse over a base whose vertex 1 is all zero
// One skin of two joints (node 0, its child node 1); primitive 0 is mesh "Body" on node 2,
// primitive 1 mesh "Hat" on node 3, both skinned; one clip turning node 1.
#pragma once

#include <vector>

#include "gltf_test_support.h"

namespace skinserve::testing {

struct TangentScenePrimitive {
  std::size_t vertex_count = 0;
  // As stored, decoded per the spec (normalized integers c / 32767), not renormalised.
  std::vector<double> positions, normals, tangents;  // 3, 3, 4 per vertex
  std::vector<int> joints;                           // 4 per vertex
  std::vector<double> weights;                       // 4 per vertex, summing to 1
  // Morph targets, dense as the file holds them: per target 3 per vertex; empty: the
  // target has no such attribute.
  std::vector<std::vector<double>> target_positions, target_normals, target_tangents;
  int tangent_accessor = -1, normal_accessor = -1;
  std::vector<int> target_tangent_accessors;  // -1 where a target has no TANGENT
};

struct TangentScene {
  Glb glb;
  std::vector<TangentScenePrimitive> primitives;
};

TangentScene MakeTangentScene();

}  // namespace skinserve::testing
