// Hand-made skinned characters for the whole-character tests, written to GLB by the test
// itself (no file on disk is read) and evaluated in float64 from the same description with
// the test support's own glTF formulas (RefPalette, RefSkin), never through the importer.
//   SeveralPrimitivesOneSkin  one skin; mesh "Body" with 3 primitives and mesh "Hat" with 1
//                             on a second node; mesh nodes carry transforms glTF ignores
//   TwoSkins                  two skeletons, one mesh each (2 and 1 primitives), different
//                             clips on each
//   MovingParent              the skinned mesh node and its skeleton under one animated
//                             node; only that node moves, so every vertex moves rigidly
//                             with it (a check that needs no skinning code at all)
//   MorphFace                 one skin; mesh "Face" (2 primitives, 3 morph targets with
//                             POSITION and NORMAL deltas, default weights) driven by a
//                             weights channel of the given interpolation, and mesh "Brow"
//                             (1 primitive, 2 targets) on its default weights only
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gltf_test_support.h"

namespace skinserve::testing {

struct ScenePrimitive {
  std::vector<float> positions, normals;  // normals: empty or 3 per vertex
  std::vector<uint8_t> joints;            // 4 per vertex (JOINTS_0)
  std::vector<float> weights;             // 4 per vertex (WEIGHTS_0), summing to 1
  std::vector<uint16_t> indices;
  // Morph targets, dense as glTF stores them: per target 3 floats per vertex; a target's
  // normal deltas may be empty (it has no NORMAL).
  std::vector<std::vector<float>> target_positions, target_normals;
};
struct SceneMesh {
  std::string name;
  std::vector<ScenePrimitive> primitives;
  std::vector<double> weights;  // the mesh's default morph weights (empty: none)
};
// A `weights` channel: per key one value per morph target of the node's mesh (CUBICSPLINE:
// in-tangents, values, out-tangents).
struct SceneWeightsChannel {
  int node = -1;
  std::string interpolation;
  std::vector<double> times;
  std::vector<double> values;
};
struct SceneNode {
  std::string name;
  std::vector<int> children;
  double t[3] = {0, 0, 0};
  double r[4] = {0, 0, 0, 1};  // x y z w
  double s[3] = {1, 1, 1};
  int mesh = -1, skin = -1;
};
struct SceneSkin {
  std::vector<int> joints;
  std::vector<Mat4> inverse_bind;
};
struct Scene {
  std::vector<SceneNode> nodes;
  std::vector<SceneMesh> meshes;
  std::vector<SceneSkin> skins;
  RefClip clip;  // LINEAR channels; written as the file's one animation
  std::vector<SceneWeightsChannel> weights_channels;  // in the same animation
};

Scene SeveralPrimitivesOneSkin();
Scene TwoSkins();
Scene MovingParent();
Scene MorphFace(const std::string& interpolation);

std::vector<uint8_t> WriteGlb(const Scene& scene);

// What a spec-following importer lists: every primitive of every node with mesh and skin,
// nodes in file order.
struct ScenePrimitiveRef {
  int node = -1, mesh = -1, primitive = -1, skin = -1;
  std::string name;  // "<mesh name>/<primitive>"
};
std::vector<ScenePrimitiveRef> SkinnedPrimitives(const Scene& scene);

// Primitive `p` skinned in float64 at time `t` of the clip (the mesh node's own transform
// plays no part, as glTF requires), after its morph targets are applied with the node's
// weights at `t` (its weights channel sampled in float64 by the test's own formulas, else
// the mesh's default weights).
RefFrame SceneFrame(const Scene& scene, const ScenePrimitiveRef& p, double t);

// The world matrix of node `node` at time `t` (column-major).
Mat4 WorldMatrix(const Scene& scene, int node, double t);

}  // namespace skinserve::testing
