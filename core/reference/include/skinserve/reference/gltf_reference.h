// An independent float64 reading and evaluation of a skinned glTF character: its own GLB
// and accessor reading (nlohmann JSON), its own sampling from the glTF spec's formulas
// (STEP, LINEAR with slerp, CUBICSPLINE Hermite), its own hierarchy and linear blend
// skinning, sharing no code with core/character or core/animation. What the glTF tests and
// skinserve-load --animate FILE check the server's poses against.
//
// Scope: skin 0 and the first primitive of the first node that has a mesh and a skin;
// translation, rotation and scale channels (weights channels are left out). Errors (a
// malformed file) are thrown as std::runtime_error or nlohmann::json::exception.
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace skinserve::gltf_reference {

// A GLB split into its JSON and BIN chunk.
struct Glb {
  nlohmann::json json;
  std::vector<uint8_t> bin;
};
Glb ParseGlb(const std::vector<uint8_t>& bytes);

// Byte offset in the BIN chunk of element `e` of accessor `a` (tightly packed or strided).
std::size_t ElementOffset(const Glb& glb, int accessor, std::size_t e);

// Accessor `a` as doubles, component after component, normalized integers converted per
// the spec.
std::vector<double> ReadAccessor(const Glb& glb, int accessor);

using Mat4 = std::array<double, 16>;  // column-major, like glTF

struct RefNode {
  int parent = -1;
  bool has_matrix = false;
  Mat4 matrix{};
  double t[3] = {0, 0, 0};
  double r[4] = {0, 0, 0, 1};  // x y z w
  double s[3] = {1, 1, 1};
};
struct RefChannel {
  int node = -1;
  std::string path;           // translation, rotation, scale
  std::string interpolation;  // LINEAR, STEP, CUBICSPLINE
  std::vector<double> times;
  std::vector<double> values;
};
struct RefClip {
  std::string name;
  double duration = 0;
  std::vector<RefChannel> channels;
};
struct RefPrimitive {
  std::size_t vertex_count = 0;
  std::vector<double> positions, normals;
  std::vector<int> joints;      // 4 per vertex (JOINTS_0)
  std::vector<double> weights;  // 4 per vertex, divided by their sum
  std::size_t index_count = 0;
};
struct RefCharacter {
  std::vector<RefNode> nodes;
  std::vector<int> joints;  // skin 0
  std::vector<Mat4> inverse_bind;
  RefPrimitive primitive;  // the first skinned primitive
  std::vector<RefClip> clips;
};
RefCharacter ReadReference(const Glb& glb);

// T * R * S per the glTF spec, column-major; the quaternion (x y z w) is normalised.
Mat4 Compose(const double t[3], const double q[4], const double s[3]);

// A channel's value at `t` per the glTF spec, written from its formulas.
std::vector<double> RefSample(const RefChannel& ch, double t);
// Every node's local transform with the clip applied at `t` (no clip: rest), then model
// matrices root down, then model(joint) * inverse_bind: 12 doubles per joint, row-major.
std::vector<double> RefPalette(const RefCharacter& ref, const RefClip* clip, double t);
// Linear blend skinning of the reference primitive in double.
struct RefFrame {
  std::vector<double> positions, normals;
};
RefFrame RefSkin(const RefPrimitive& primitive, const std::vector<double>& palette);

}  // namespace skinserve::gltf_reference
