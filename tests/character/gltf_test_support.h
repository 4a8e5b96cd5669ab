// Test support for the glTF importer and animation: the assets, GLB editing in memory, and
// an independent float64 reading and evaluation of a skinned glTF (own JSON/accessor
// reading, own slerp/Hermite, own hierarchy, own skinning) that shares no code with core.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace skinserve::testing {

// The test characters live in the repository (tests/assets/gltf, credited in its
// SOURCES.md); CMake passes the folder in. A missing one is a broken checkout: the test
// fails saying so, it never skips.
std::string AssetPath(const std::string& file);
bool AssetExists(const std::string& file);
#define REQUIRE_ASSET(file)                                                           \
  ASSERT_TRUE(::skinserve::testing::AssetExists(file))                                \
      << "test asset " << ::skinserve::testing::AssetPath(file)                       \
      << " is missing: it is part of the repository (tests/assets/gltf); restore it " \
         "with git checkout"

std::vector<uint8_t> ReadBytes(const std::string& path);

// A GLB split into its JSON and BIN chunk, to edit and put back together.
struct Glb {
  nlohmann::json json;
  std::vector<uint8_t> bin;
};
Glb ParseGlb(const std::vector<uint8_t>& bytes);
std::vector<uint8_t> BuildGlb(const Glb& glb);
// Appends `bytes` to the BIN chunk as a new bufferView (4-byte aligned); returns its index.
int AppendBufferView(Glb& glb, const std::vector<uint8_t>& bytes);
// Appends an accessor over a new bufferView holding `bytes`; returns its index.
int AppendAccessor(Glb& glb, const std::vector<uint8_t>& bytes, int component_type,
                   const std::string& type, std::size_t count, bool normalized = false);
// Byte offset in the BIN chunk of element `e` of accessor `a` (tightly packed or strided).
std::size_t ElementOffset(const Glb& glb, int accessor, std::size_t e);

// Accessor `a` as doubles, component after component, normalized integers converted per
// the spec.
std::vector<double> ReadAccessor(const Glb& glb, int accessor);

// ---- Independent float64 model of a skinned glTF ----
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

// Quaternions q and -q are one rotation: the distance between two as rotations.
double QuatDistance(const double a[4], const double b[4]);

}  // namespace skinserve::testing
