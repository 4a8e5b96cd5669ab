// Malformed glTF built by editing a valid character in memory: each gives INVALID_ARGUMENT
// naming the object, and none crashes or reads out of bounds (the sanitizer run is in
// this folder's CMakeLists.txt).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "gltf_test_support.h"
#include "skinserve/character/gltf_import.h"

namespace skinserve::testing {
namespace {

using nlohmann::json;

class MalformedGltfTest : public ::testing::Test {
 protected:
  void SetUp() override {
    REQUIRE_ASSET("RiggedSimple.glb");
    bytes_ = ReadBytes(AssetPath("RiggedSimple.glb"));
    glb_ = ParseGlb(bytes_);
  }

  json& Attributes() { return glb_.json["meshes"][0]["primitives"][0]["attributes"]; }
  int Accessor(const char* attribute) { return Attributes()[attribute].get<int>(); }
  template <typename T>
  void Patch(int accessor, std::size_t element, int component, T value) {
    std::memcpy(&glb_.bin.at(ElementOffset(glb_, accessor, element) + sizeof(T) * component),
                &value, sizeof(T));
  }
  // The first sampler with at least two keys.
  std::size_t SamplerWithKeys() {
    const json& samplers = glb_.json["animations"][0]["samplers"];
    for (std::size_t s = 0; s < samplers.size(); ++s) {
      if (glb_.json["accessors"][samplers[s]["input"].get<size_t>()]["count"] >= 2) return s;
    }
    ADD_FAILURE() << "no sampler with two keys";
    return 0;
  }

  // INVALID_ARGUMENT whose message contains each of `mentions`.
  void ExpectInvalid(const std::vector<uint8_t>& bytes,
                     std::initializer_list<std::string> mentions) {
    auto character = LoadGltfBytes(bytes);
    ASSERT_FALSE(character.ok()) << "accepted; expected an error mentioning " << *mentions.begin();
    EXPECT_EQ(character.status().code(), StatusCode::kInvalidArgument)
        << character.status().ToString();
    for (const std::string& m : mentions) {
      EXPECT_NE(character.status().message().find(m), std::string::npos)
          << "\"" << character.status().message() << "\" does not mention \"" << m << "\"";
    }
  }
  void ExpectInvalid(std::initializer_list<std::string> mentions) {
    ExpectInvalid(BuildGlb(glb_), mentions);
  }

  std::vector<uint8_t> bytes_;
  Glb glb_;
};

TEST_F(MalformedGltfTest, UneditedAssetImports) {
  auto character = LoadGltfBytes(BuildGlb(glb_));
  EXPECT_TRUE(character.ok()) << character.status().ToString();
}

TEST_F(MalformedGltfTest, TruncatedGlbAtManyLengths) {
  uint32_t json_length;
  std::memcpy(&json_length, &bytes_[12], 4);
  const std::size_t json_end = 20 + json_length;
  for (std::size_t length :
       {std::size_t{0}, std::size_t{1}, std::size_t{4}, std::size_t{12}, std::size_t{19},
        std::size_t{20}, std::size_t{21}, std::size_t{100}, json_end - 1, json_end, json_end + 4,
        json_end + 8, json_end + 9, bytes_.size() / 2, bytes_.size() - 4, bytes_.size() - 1}) {
    SCOPED_TRACE(length);
    const std::vector<uint8_t> cut(bytes_.begin(), bytes_.begin() + static_cast<long>(length));
    ExpectInvalid(cut, {length >= 4 ? "GLB" : "glTF"});
  }
}

// A shorter BIN chunk whose headers were fixed up to agree: the buffer is too short for
// the bufferViews, which must be caught before reading.
TEST_F(MalformedGltfTest, ShortBinChunkWithConsistentHeaders) {
  glb_.bin.resize(glb_.bin.size() / 2);
  glb_.json["buffers"][0]["byteLength"] = glb_.bin.size();
  auto character = LoadGltfBytes(BuildGlb(glb_));
  ASSERT_FALSE(character.ok());
  EXPECT_EQ(character.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(character.status().message().find("buffer"), std::string::npos)
      << character.status().message();
}

TEST_F(MalformedGltfTest, AccessorCountPastItsBufferView) {
  glb_.json["accessors"][Accessor("POSITION")]["count"] = 100000;
  ExpectInvalid(
      {"meshes[0].primitives[0].attributes.POSITION", "accessor 0", "reads past bufferView"});
}

TEST_F(MalformedGltfTest, AccessorByteOffsetPastItsBufferView) {
  glb_.json["accessors"][Accessor("NORMAL")]["byteOffset"] = 16;
  ExpectInvalid({"attributes.NORMAL", "reads past bufferView"});
}

TEST_F(MalformedGltfTest, HugeAccessorCountDoesNotOverflow) {
  glb_.json["accessors"][Accessor("WEIGHTS_0")]["count"] = std::numeric_limits<int64_t>::max();
  auto character = LoadGltfBytes(BuildGlb(glb_));
  ASSERT_FALSE(character.ok());
  EXPECT_EQ(character.status().code(), StatusCode::kInvalidArgument);
}

TEST_F(MalformedGltfTest, BufferViewPastItsBuffer) {
  const int view = glb_.json["accessors"][Accessor("JOINTS_0")]["bufferView"];
  glb_.json["bufferViews"][view]["byteOffset"] = glb_.bin.size() - 8;
  ExpectInvalid(
      {"attributes.JOINTS_0", "bufferView " + std::to_string(view), "reaches past buffer 0"});
}

TEST_F(MalformedGltfTest, BufferViewStrideSmallerThanElement) {
  const int view = glb_.json["accessors"][Accessor("POSITION")]["bufferView"];
  glb_.json["bufferViews"][view]["byteStride"] = 8;
  ExpectInvalid({"attributes.POSITION", "byteStride 8"});
}

TEST_F(MalformedGltfTest, AccessorAndBufferViewIndicesOutOfRange) {
  Attributes()["NORMAL"] = 999;
  ExpectInvalid({"attributes.NORMAL", "accessor 999 does not exist"});
  Attributes()["NORMAL"] = 1;
  glb_.json["accessors"][1]["bufferView"] = 77;
  ExpectInvalid({"attributes.NORMAL", "bufferView 77"});
}

TEST_F(MalformedGltfTest, JointIndexPastTheSkin) {
  Patch<uint8_t>(Accessor("JOINTS_0"), 7, 2, 200);
  ExpectInvalid({"meshes[0].primitives[0].attributes.JOINTS_0", "vertex 7", "joint 200"});
}

TEST_F(MalformedGltfTest, WeightsOfAComponentTypeTheSpecForbids) {
  glb_.json["accessors"][Accessor("WEIGHTS_0")]["componentType"] = 5120;  // BYTE
  ExpectInvalid({"attributes.WEIGHTS_0", "BYTE"});
}

TEST_F(MalformedGltfTest, JointsOfTheWrongType) {
  glb_.json["accessors"][Accessor("JOINTS_0")]["type"] = "VEC3";
  ExpectInvalid({"attributes.JOINTS_0", "VEC3", "expected VEC4"});
}

TEST_F(MalformedGltfTest, NegativeNonFiniteAndAllZeroWeights) {
  const std::vector<uint8_t> bin = glb_.bin;
  Patch<float>(Accessor("WEIGHTS_0"), 5, 1, -0.5f);
  ExpectInvalid({"attributes.WEIGHTS_0", "vertex 5"});
  glb_.bin = bin;
  Patch<float>(Accessor("WEIGHTS_0"), 6, 0, std::numeric_limits<float>::quiet_NaN());
  ExpectInvalid({"attributes.WEIGHTS_0", "vertex 6"});
  glb_.bin = bin;
  for (int c = 0; c < 4; ++c) Patch<float>(Accessor("WEIGHTS_0"), 9, c, 0.0f);
  ExpectInvalid({"WEIGHTS", "vertex 9", "zero"});
}

TEST_F(MalformedGltfTest, NonIncreasingAnimationTimes) {
  const std::size_t s = SamplerWithKeys();
  const int input = glb_.json["animations"][0]["samplers"][s]["input"];
  float t0;
  std::memcpy(&t0, &glb_.bin[ElementOffset(glb_, input, 0)], 4);
  Patch<float>(input, 1, 0, t0);
  ExpectInvalid(
      {"animations[0].samplers[" + std::to_string(s) + "].input", "key 1", "strictly increase"});
}

TEST_F(MalformedGltfTest, AnimationOutputCountOrInterpolationWrong) {
  const std::size_t s = SamplerWithKeys();
  json& sampler = glb_.json["animations"][0]["samplers"][s];
  sampler["interpolation"] = "CUBICSPLINE";  // needs 3 values per key
  ExpectInvalid({"animations[0].samplers[" + std::to_string(s) + "].output"});
  sampler["interpolation"] = "SMOOTH";
  ExpectInvalid({"samplers[" + std::to_string(s) + "].interpolation", "SMOOTH"});
}

TEST_F(MalformedGltfTest, InverseBindCountMismatch) {
  glb_.json["accessors"][glb_.json["skins"][0]["inverseBindMatrices"].get<int>()]["count"] = 3;
  ExpectInvalid({"skins[0].inverseBindMatrices", "3 matrices", "4 joints"});
}

TEST_F(MalformedGltfTest, SkinJointNotANode) {
  glb_.json["skins"][0]["joints"][2] = 40;
  ExpectInvalid({"skins[0].joints[2] = 40"});
}

// Without its skin the mesh is a rigid part (what a viewer draws); without the mesh node
// nothing is left to skin.
TEST_F(MalformedGltfTest, NoPrimitiveToSkin) {
  glb_.json["nodes"][4].erase("skin");
  auto rigid = LoadGltfBytes(BuildGlb(glb_));
  ASSERT_TRUE(rigid.ok()) << rigid.status().ToString();
  ASSERT_EQ(rigid->primitives.size(), 1u);
  EXPECT_TRUE(rigid->primitives[0].rigid());
  EXPECT_EQ(rigid->primitives[0].arrays.influences, 1u);
  glb_.json["nodes"][4].erase("mesh");
  ExpectInvalid({"no primitive to skin"});
}

TEST_F(MalformedGltfTest, NotTriangles) {
  glb_.json["meshes"][0]["primitives"][0]["mode"] = 1;
  ExpectInvalid({"meshes[0].primitives[0].mode", "triangles"});
}

TEST_F(MalformedGltfTest, TriangleIndexPastTheVertices) {
  const int indices = glb_.json["meshes"][0]["primitives"][0]["indices"];
  Patch<uint16_t>(indices, 11, 0, 60000);
  ExpectInvalid({"meshes[0].primitives[0].indices[11] = 60000"});
}

// A sparse POSITION substituting vertices 3 and 700 (UNSIGNED_SHORT indices).
class SparseGltfTest : public MalformedGltfTest {
 protected:
  void SetUp() override {
    MalformedGltfTest::SetUp();
    if (HasFatalFailure()) return;
    const std::vector<uint16_t> indices = {3, 700};
    const std::vector<float> values = {1.5f, -2.0f, 0.25f, 4.0f, 5.0f, -6.0f};
    indices_view_ = AppendBufferView(glb_, Bytes(indices));
    values_view_ = AppendBufferView(glb_, Bytes(values));
    Sparse() = {{"count", 2},
                {"indices", {{"bufferView", indices_view_}, {"componentType", 5123}}},
                {"values", {{"bufferView", values_view_}}}};
  }
  template <typename T>
  static std::vector<uint8_t> Bytes(const std::vector<T>& v) {
    std::vector<uint8_t> out(v.size() * sizeof(T));
    std::memcpy(out.data(), v.data(), out.size());
    return out;
  }
  json& Sparse() { return glb_.json["accessors"][Accessor("POSITION")]["sparse"]; }
  int indices_view_ = -1, values_view_ = -1;
};

TEST_F(SparseGltfTest, SubstitutesTheListedVerticesOnly) {
  const std::vector<double> base = ReadAccessor(glb_, Accessor("POSITION"));
  auto character = LoadGltfBytes(BuildGlb(glb_));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const std::vector<float>& got = character->primitives[0].arrays.positions;
  ASSERT_EQ(got.size(), base.size());
  const double replaced[2][3] = {{1.5, -2.0, 0.25}, {4.0, 5.0, -6.0}};
  for (std::size_t i = 0; i < got.size(); ++i) {
    const std::size_t v = i / 3;
    const double expected = v == 3 ? replaced[0][i % 3] : v == 700 ? replaced[1][i % 3] : base[i];
    ASSERT_EQ(got[i], expected) << "vertex " << v;
  }
}

TEST_F(SparseGltfTest, IndexPastTheCountOrNotIncreasing) {
  const std::size_t at = glb_.json["bufferViews"][indices_view_]["byteOffset"].get<std::size_t>();
  const std::vector<uint8_t> bin = glb_.bin;
  const uint16_t past = 960;
  std::memcpy(&glb_.bin[at + 2], &past, 2);
  ExpectInvalid({"attributes.POSITION", "sparse.indices[1] = 960", "count 960"});
  glb_.bin = bin;
  const uint16_t back = 2;
  std::memcpy(&glb_.bin[at + 2], &back, 2);
  ExpectInvalid({"attributes.POSITION", "sparse.indices[1] = 2", "does not increase"});
}

TEST_F(SparseGltfTest, CountIndexTypeAndViewsChecked) {
  const json sparse = Sparse();
  Sparse()["count"] = 961;
  ExpectInvalid({"attributes.POSITION", "sparse.count is 961", "1..960"});
  Sparse() = sparse;
  Sparse()["count"] = 0;
  ExpectInvalid({"attributes.POSITION", "sparse.count is 0"});
  Sparse() = sparse;
  Sparse()["indices"]["componentType"] = 5126;
  ExpectInvalid({"attributes.POSITION", "sparse.indices.componentType", "FLOAT"});
  Sparse() = sparse;
  Sparse()["count"] = 3;  // the values view holds two VEC3
  ExpectInvalid({"attributes.POSITION", "sparse.indices", "reads past bufferView"});
  Sparse() = sparse;
  Sparse()["values"]["byteOffset"] = 4;
  ExpectInvalid({"attributes.POSITION", "sparse.values", "reads past bufferView"});
  Sparse() = sparse;
  Sparse()["values"]["bufferView"] = 500;
  ExpectInvalid({"attributes.POSITION", "sparse.values", "bufferView 500"});
}

// KHR_mesh_quantization allows integer POSITION (byte, short, normalized or not) and
// normalized BYTE/SHORT NORMAL; the rest stays refused.
TEST_F(MalformedGltfTest, QuantizedAttributesOfForbiddenComponentTypes) {
  glb_.json["extensionsRequired"] = {"KHR_mesh_quantization"};
  glb_.json["extensionsUsed"] = {"KHR_mesh_quantization"};
  json& position = glb_.json["accessors"][Accessor("POSITION")];
  json& normal = glb_.json["accessors"][Accessor("NORMAL")];
  const json position_kept = position, normal_kept = normal;
  position["componentType"] = 5125;  // UNSIGNED_INT
  ExpectInvalid({"attributes.POSITION", "UNSIGNED_INT", "allowed: FLOAT, BYTE"});
  position = position_kept;
  normal["componentType"] = 5121;  // UNSIGNED_BYTE
  ExpectInvalid({"attributes.NORMAL", "UNSIGNED_BYTE", "allowed: FLOAT, BYTE, SHORT"});
  normal["componentType"] = 5122;  // SHORT, not normalized
  ExpectInvalid({"attributes.NORMAL", "SHORT", "normalized"});
  normal = normal_kept;
  glb_.json["accessors"][Accessor("WEIGHTS_0")]["componentType"] = 5122;  // SHORT
  ExpectInvalid({"attributes.WEIGHTS_0", "SHORT", "allowed"});
}

// The extension itself is accepted; any unknown one still is not (next test).
TEST_F(MalformedGltfTest, MeshQuantizationRequiredIsAccepted) {
  glb_.json["extensionsRequired"] = {"KHR_mesh_quantization", "KHR_materials_unlit"};
  glb_.json["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_materials_unlit"};
  auto character = LoadGltfBytes(BuildGlb(glb_));
  EXPECT_TRUE(character.ok()) << character.status().ToString();
}

TEST_F(MalformedGltfTest, HierarchyCycleAndTwoParents) {
  json nodes = glb_.json["nodes"];
  glb_.json["nodes"][0]["children"] = {3};  // 3 is already a child of 5
  ExpectInvalid({"nodes[3] is a child of both"});
  glb_.json["nodes"] = nodes;
  glb_.json["nodes"][5]["children"] = {4};  // 3 -> 2 -> 1 -> 0 -> 3
  glb_.json["nodes"][0]["children"] = {3};
  ExpectInvalid({"ancestor", "cycles"});
}

TEST_F(MalformedGltfTest, UnsupportedRequiredExtension) {
  glb_.json["extensionsRequired"] = {"KHR_mesh_quantization", "KHR_draco_mesh_compression"};
  glb_.json["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_draco_mesh_compression"};
  ExpectInvalid({"extensionsRequired: KHR_draco_mesh_compression is not supported"});
}

TEST_F(MalformedGltfTest, GarbageBytes) {
  std::mt19937 rng(7);
  std::vector<uint8_t> garbage(4096);
  for (uint8_t& b : garbage) b = static_cast<uint8_t>(rng());
  ExpectInvalid(garbage, {"glTF"});
  std::memcpy(garbage.data(), "glTF", 4);  // the magic, then noise
  ExpectInvalid(garbage, {"GLB"});
  for (const char* text : {"{not json", "[]", "{}", "null", "{\"asset\":{\"version\":\"2.0\"}}"}) {
    SCOPED_TRACE(text);
    ExpectInvalid(std::vector<uint8_t>(text, text + std::strlen(text)), {});
  }
}

// Random edits of the JSON's numbers and of the bytes: whatever they do, an import returns
// OK or INVALID_ARGUMENT and never crashes or reads out of bounds (ASan run: see
// CMakeLists.txt).
TEST_F(MalformedGltfTest, RandomEditsNeverCrash) {
  std::mt19937 rng(2024);
  std::vector<json*> numbers;
  std::function<void(json&)> collect = [&](json& j) {
    if (j.is_number()) numbers.push_back(&j);
    if (j.is_structured())
      for (json& child : j) collect(child);
  };
  const int64_t kValues[] = {-1,
                             0,
                             1,
                             2,
                             3,
                             4,
                             5,
                             7,
                             255,
                             5120,
                             5123,
                             5125,
                             65535,
                             1 << 30,
                             std::numeric_limits<int32_t>::max(),
                             int64_t{1} << 40};
  int accepted = 0;
  for (int i = 0; i < 400; ++i) {
    Glb edited = glb_;
    numbers.clear();
    collect(edited.json);
    for (int e = 0; e < 1 + i % 3; ++e) {
      json& target = *numbers[rng() % numbers.size()];
      target = kValues[rng() % std::size(kValues)];
    }
    std::vector<uint8_t> bytes = BuildGlb(edited);
    if (i % 4 == 0) {  // and some raw byte flips anywhere
      for (int f = 0; f < 8; ++f)
        bytes[rng() % bytes.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
    }
    auto character = LoadGltfBytes(bytes);
    if (character.ok()) {
      ++accepted;
    } else {
      ASSERT_EQ(character.status().code(), StatusCode::kInvalidArgument)
          << character.status().ToString();
      ASSERT_FALSE(character.status().message().empty());
    }
  }
  RecordProperty("accepted", accepted);
}

}  // namespace
}  // namespace skinserve::testing
