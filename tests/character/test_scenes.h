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
//   RigidParts                one skin and meshes on nodes without a skin (rigid parts):
//                             under an animated joint, on an animated node whose parent is
//                             animated (non-uniform animated scale), one mesh on two nodes
//   Quantized                 KHR_mesh_quantization as gltfpack writes it: int16 positions
//                             with the dequantization in the rigid mesh node's transform or
//                             the skin's inverse bind matrices, normalized uint16 positions,
//                             int8/int16 normals, uint8/uint16 weights, padded strides
//   WalkingFace               a box figure walking in place (skinned body, 8 joints) with a
//                             rigid head on an animated node whose 2 morph targets (mouth
//                             open, eyes shut) follow a weights channel; kept as
//                             tests/assets/gltf/WalkingFace.glb for the docs' picture
//   Sparse                    sparse accessors: positions over a base, normals and rigid
//                             positions with no base (zeros), weights with uint32 indices
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gltf_test_support.h"

namespace skinserve::testing {

// How WriteGlb stores a primitive's attributes. Component types are glTF's (5126 FLOAT,
// 5120 BYTE, 5121 UNSIGNED_BYTE, 5122 SHORT, 5123 UNSIGNED_SHORT); integer normals and
// weights are normalized. The scene's values must be what the stored integers decode to
// (Snap* below make them so). sparse_*: 0 dense, else the sparse indices' component type.
struct SceneEncoding {
  int position_type = 5126;
  bool position_normalized = false;
  int normal_type = 5126;
  int weight_type = 5126;
  int sparse_positions = 0;        // every odd vertex substituted over a base of garbage
  bool positions_no_base = false;  // sparse positions: no bufferView (zeros) + the non-zero ones
  int sparse_normals = 0;          // no bufferView; every vertex substituted
  int sparse_weights = 0;          // every odd vertex substituted over a base of garbage
};
struct ScenePrimitive {
  std::vector<float> positions, normals;  // normals: empty or 3 per vertex
  std::vector<uint8_t> joints;            // 4 per vertex (JOINTS_0); empty: not skinned
  std::vector<float> weights;             // 4 per vertex (WEIGHTS_0), summing to 1
  std::vector<uint16_t> indices;
  // Morph targets, dense as glTF stores them: per target 3 floats per vertex; a target's
  // normal deltas may be empty (it has no NORMAL).
  std::vector<std::vector<float>> target_positions, target_normals;
  SceneEncoding encoding;
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
  std::vector<Mat4> inverse_bind;  // rest world^-1 * bind_shape, filled by the scene
  Mat4 bind_shape = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // e.g. dequantization
};
struct Scene {
  std::vector<SceneNode> nodes;
  std::vector<SceneMesh> meshes;
  std::vector<SceneSkin> skins;
  RefClip clip;  // LINEAR channels; written as the file's one animation
  std::vector<SceneWeightsChannel> weights_channels;  // in the same animation
  std::vector<std::string> extensions_required;
};

Scene SeveralPrimitivesOneSkin();
Scene TwoSkins();
Scene MovingParent();
Scene MorphFace(const std::string& interpolation);
Scene RigidParts();
Scene Quantized();
Scene Sparse();
Scene WalkingFace();

std::vector<uint8_t> WriteGlb(const Scene& scene);

// What a spec-following importer lists: every primitive of every node with a mesh (skin
// -1: a rigid part, following the node), nodes in file order.
struct ScenePrimitiveRef {
  int node = -1, mesh = -1, primitive = -1, skin = -1;
  std::string name;  // "<mesh name>/<primitive>"
};
std::vector<ScenePrimitiveRef> SkinnedPrimitives(const Scene& scene);

// Morph targets are applied first, with the node's weights at `t` (its weights channel
// sampled in float64 by the test's own formulas, else the mesh's default weights; a rigid
// part's position deltas only). Primitive `p` at time `t` of the clip in float64: skinned
// (the mesh node's own transform plays no part, as glTF requires), or for a rigid part its
// node's world matrix applied to the positions and its inverse transpose to the normals
// (renormalised).
RefFrame SceneFrame(const Scene& scene, const ScenePrimitiveRef& p, double t);

// The world matrix of node `node` at time `t` (column-major).
Mat4 WorldMatrix(const Scene& scene, int node, double t);

}  // namespace skinserve::testing
