// The glTF importer on the repository's test characters (tests/assets/gltf) and on variants of them
// edited in memory: figures from SOURCES.md, and every array against an independent reading of the
// file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "gltf_test_support.h"
#include "skinserve/character/gltf_import.h"

namespace skinserve::testing {
namespace {

using nlohmann::json;

// As SOURCES.md states them (read from the files by their author, not by this code).
struct AssetFacts {
  const char* file;
  uint32_t vertices;
  uint32_t joints;
  uint32_t influences;
  bool normals;
  const char* clip;
  double duration;
  std::size_t channels;
};

const AssetFacts kAssets[] = {
    {"CesiumMan.glb", 3273, 19, 4, true, "Anim_0", 2.000, 57},
    {"RiggedSimple.glb", 960, 4, 4, true, "Anim_0_Armature", 6.667, 12},
};

Result<Character> Load(const std::vector<uint8_t>& bytes) { return LoadGltfBytes(bytes); }

class AssetImportTest : public ::testing::TestWithParam<AssetFacts> {};

TEST_P(AssetImportTest, MatchesSourcesMd) {
  const AssetFacts& facts = GetParam();
  REQUIRE_ASSET(facts.file);
  auto character = LoadGltfFile(AssetPath(facts.file));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  ASSERT_EQ(character->primitives.size(), 1u);
  const SkinnedPrimitive& p = character->primitives[0];
  EXPECT_EQ(p.arrays.vertex_count, facts.vertices);
  EXPECT_EQ(p.arrays.joint_count, facts.joints);
  EXPECT_EQ(p.arrays.influences, facts.influences);
  EXPECT_EQ(!p.arrays.normals.empty(), facts.normals);
  ASSERT_EQ(character->clips.size(), 1u);
  const AnimationClip* clip = character->FindClip("");
  ASSERT_NE(clip, nullptr);
  EXPECT_EQ(clip, character->FindClip(facts.clip));
  EXPECT_EQ(character->FindClip("no such clip"), nullptr);
  EXPECT_EQ(clip->name, facts.clip);
  EXPECT_NEAR(clip->duration, facts.duration, 0.0005);  // SOURCES.md rounds to 1 ms
  EXPECT_EQ(clip->channels.size(), facts.channels);
  ASSERT_EQ(p.skin, 0);
  EXPECT_EQ(character->skins[0].joints.size(), facts.joints);
  // The importer's output passes the engine's validator with the default (reject) policy.
  auto mesh = Mesh::Create(p.arrays);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ(mesh.value()->normalized_vertices(), 0u);
}

TEST_P(AssetImportTest, ArraysMatchAnIndependentReading) {
  const AssetFacts& facts = GetParam();
  REQUIRE_ASSET(facts.file);
  const std::vector<uint8_t> bytes = ReadBytes(AssetPath(facts.file));
  const RefCharacter ref = ReadReference(ParseGlb(bytes));
  auto character = Load(bytes);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const SkinnedPrimitive& p = character->primitives[0];
  ASSERT_EQ(p.arrays.positions.size(), ref.primitive.positions.size());
  for (std::size_t i = 0; i < ref.primitive.positions.size(); ++i) {
    ASSERT_EQ(p.arrays.positions[i], ref.primitive.positions[i]) << i;  // floats, copied
    ASSERT_EQ(p.arrays.normals[i], ref.primitive.normals[i]) << i;
  }
  ASSERT_EQ(p.arrays.joints.size(), ref.primitive.joints.size());
  for (std::size_t i = 0; i < ref.primitive.joints.size(); ++i) {
    ASSERT_EQ(p.arrays.joints[i], ref.primitive.joints[i]) << i;
    // A float quotient of the file's weights by their sum: within float rounding of 1.
    ASSERT_NEAR(p.arrays.weights[i], ref.primitive.weights[i], 1.2e-7) << i;
  }
  EXPECT_EQ(p.indices.size(), ref.primitive.index_count);
  for (uint32_t index : p.indices) ASSERT_LT(index, p.arrays.vertex_count);

  ASSERT_EQ(character->nodes.size(), ref.nodes.size());
  for (std::size_t i = 0; i < ref.nodes.size(); ++i) {
    const CharacterNode& n = character->nodes[i];
    const RefNode& r = ref.nodes[i];
    EXPECT_EQ(n.parent, r.parent) << "node " << i;
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(n.translation[c], static_cast<float>(r.t[c])) << "node " << i;
      EXPECT_EQ(n.scale[c], static_cast<float>(r.s[c])) << "node " << i;
    }
    // The importer normalises rotations; the files' are unit to float rounding.
    const double q[4] = {n.rotation.x, n.rotation.y, n.rotation.z, n.rotation.w};
    EXPECT_LT(QuatDistance(q, r.r), 2e-7) << "node " << i;
  }
  const CharacterSkin& skin = character->skins[0];
  ASSERT_EQ(skin.joints, ref.joints);
  for (std::size_t j = 0; j < ref.joints.size(); ++j) {
    for (int k = 0; k < 16; ++k) {
      EXPECT_EQ(skin.inverse_bind[j][k / 4][k % 4], ref.inverse_bind[j][static_cast<size_t>(k)]);
    }
  }
  const AnimationClip& clip = character->clips[0];
  ASSERT_EQ(clip.channels.size(), ref.clips[0].channels.size());
  for (std::size_t c = 0; c < clip.channels.size(); ++c) {
    const AnimationChannel& ch = clip.channels[c];
    const RefChannel& rc = ref.clips[0].channels[c];
    EXPECT_EQ(ch.node, rc.node);
    const char* path = ch.path == ChannelPath::kTranslation ? "translation"
                       : ch.path == ChannelPath::kRotation  ? "rotation"
                                                            : "scale";
    EXPECT_EQ(path, rc.path);
    const char* interpolation = ch.interpolation == Interpolation::kLinear ? "LINEAR"
                                : ch.interpolation == Interpolation::kStep ? "STEP"
                                                                           : "CUBICSPLINE";
    EXPECT_EQ(interpolation, rc.interpolation);
    ASSERT_EQ(ch.times.size(), rc.times.size());
    for (std::size_t k = 0; k < rc.times.size(); ++k) EXPECT_EQ(ch.times[k], rc.times[k]);
    ASSERT_EQ(ch.values.size(), rc.values.size());
    for (std::size_t k = 0; k < rc.values.size(); ++k) EXPECT_EQ(ch.values[k], rc.values[k]);
  }
}

INSTANTIATE_TEST_SUITE_P(Assets, AssetImportTest, ::testing::ValuesIn(kAssets),
                         [](const auto& name_info) {
                           std::string name = name_info.param.file;
                           return name.substr(0, name.find('.'));
                         });

// The same character as .gltf JSON with its buffer in a .bin next to it, and with the
// buffer inline as a data: URI.
TEST(GltfImportTest, GltfWithBinFileAndDataUriImportLikeTheGlb) {
  REQUIRE_ASSET("RiggedSimple.glb");
  const std::vector<uint8_t> bytes = ReadBytes(AssetPath("RiggedSimple.glb"));
  auto from_glb = Load(bytes);
  ASSERT_TRUE(from_glb.ok()) << from_glb.status().ToString();
  Glb glb = ParseGlb(bytes);

  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("skinserve_gltf_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  json text = glb.json;
  text["buffers"][0]["uri"] = "rigged simple.bin";
  std::ofstream(dir / "rigged.gltf") << text.dump();
  std::ofstream(dir / "rigged simple.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(glb.bin.data()),
             static_cast<std::streamsize>(glb.bin.size()));
  auto from_gltf = LoadGltfFile((dir / "rigged.gltf").string());
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(from_gltf.ok()) << from_gltf.status().ToString();
  EXPECT_EQ(from_gltf->primitives[0].arrays.positions, from_glb->primitives[0].arrays.positions);
  EXPECT_EQ(from_gltf->primitives[0].arrays.weights, from_glb->primitives[0].arrays.weights);
  EXPECT_EQ(from_gltf->clips[0].channels.size(), from_glb->clips[0].channels.size());

  static const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string uri = "data:application/octet-stream;base64,";
  for (std::size_t i = 0; i < glb.bin.size(); i += 3) {
    uint32_t chunk = uint32_t{glb.bin[i]} << 16;
    if (i + 1 < glb.bin.size()) chunk |= uint32_t{glb.bin[i + 1]} << 8;
    if (i + 2 < glb.bin.size()) chunk |= glb.bin[i + 2];
    uri += kBase64[(chunk >> 18) & 63];
    uri += kBase64[(chunk >> 12) & 63];
    uri += i + 1 < glb.bin.size() ? kBase64[(chunk >> 6) & 63] : '=';
    uri += i + 2 < glb.bin.size() ? kBase64[chunk & 63] : '=';
  }
  text["buffers"][0]["uri"] = uri;
  const std::string dumped = text.dump();
  auto from_data_uri =
      LoadGltfBytes(std::span(reinterpret_cast<const uint8_t*>(dumped.data()), dumped.size()));
  ASSERT_TRUE(from_data_uri.ok()) << from_data_uri.status().ToString();
  EXPECT_EQ(from_data_uri->primitives[0].arrays.joints, from_glb->primitives[0].arrays.joints);
}

TEST(GltfImportTest, MissingFileNamesThePath) {
  auto character = LoadGltfFile("/nonexistent/skinserve/character.glb");
  ASSERT_FALSE(character.ok());
  EXPECT_EQ(character.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(character.status().message().find("/nonexistent/skinserve/character.glb"),
            std::string::npos);
}

// Nodes given as matrices (including a mirror) decompose to the TRS that composes them.
TEST(GltfImportTest, MatrixNodesDecomposeToTheirTrs) {
  REQUIRE_ASSET("CesiumMan.glb");
  const std::vector<uint8_t> bytes = ReadBytes(AssetPath("CesiumMan.glb"));
  Glb glb = ParseGlb(bytes);
  const RefCharacter ref = ReadReference(glb);
  std::vector<Mat4> matrices;
  for (std::size_t i = 0; i < ref.nodes.size(); ++i) {
    RefNode n = ref.nodes[i];
    if (i == 12) n.s[1] = -1.5;  // a mirror: one negative scale
    matrices.push_back(Compose(n.t, n.r, n.s));
    json& node = glb.json["nodes"][i];
    node.erase("translation");
    node.erase("rotation");
    node.erase("scale");
    node["matrix"] = matrices.back();
  }
  auto character = Load(BuildGlb(glb));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  for (std::size_t i = 0; i < matrices.size(); ++i) {
    const CharacterNode& n = character->nodes[i];
    const double t[3] = {n.translation.x, n.translation.y, n.translation.z};
    const double q[4] = {n.rotation.x, n.rotation.y, n.rotation.z, n.rotation.w};
    const double s[3] = {n.scale.x, n.scale.y, n.scale.z};
    const Mat4 again = Compose(t, q, s);
    for (int k = 0; k < 16; ++k) {
      EXPECT_NEAR(again[static_cast<size_t>(k)], matrices[i][static_cast<size_t>(k)], 1e-6)
          << "node " << i << " element " << k;
    }
  }

  glb.json["nodes"][3]["matrix"] = {1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // shear
  auto sheared = Load(BuildGlb(glb));
  ASSERT_FALSE(sheared.ok());
  EXPECT_EQ(sheared.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(sheared.status().message().find("nodes[3].matrix"), std::string::npos)
      << sheared.status().message();
}

std::vector<uint8_t> Bytes(const void* data, std::size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  return {p, p + size};
}

// Quantized weights (UNSIGNED_BYTE and UNSIGNED_SHORT, normalized), UNSIGNED_SHORT joints
// and a second set of four influences: read per spec and renormalised per vertex.
TEST(GltfImportTest, QuantizedWeightsShortJointsAndEightInfluences) {
  REQUIRE_ASSET("RiggedSimple.glb");
  Glb glb = ParseGlb(ReadBytes(AssetPath("RiggedSimple.glb")));
  const RefCharacter ref = ReadReference(glb);
  const std::size_t v_count = ref.primitive.vertex_count;
  std::vector<uint8_t> w0;
  std::vector<uint16_t> j0, j1, w1;
  for (std::size_t v = 0; v < v_count; ++v) {
    for (int k = 0; k < 4; ++k) {
      const std::size_t i = 4 * v + static_cast<std::size_t>(k);
      w0.push_back(static_cast<uint8_t>(std::lround(ref.primitive.weights[i] * 255)));
      j0.push_back(static_cast<uint16_t>(ref.primitive.joints[i]));
      j1.push_back(static_cast<uint16_t>((ref.primitive.joints[i] + 1) % 4));
      w1.push_back(static_cast<uint16_t>((v * 7 + static_cast<std::size_t>(k) * 1000) % 9000));
    }
  }
  json& attributes = glb.json["meshes"][0]["primitives"][0]["attributes"];
  attributes["WEIGHTS_0"] = AppendAccessor(glb, w0, 5121, "VEC4", v_count, true);
  attributes["JOINTS_0"] =
      AppendAccessor(glb, Bytes(j0.data(), 2 * j0.size()), 5123, "VEC4", v_count);
  attributes["JOINTS_1"] =
      AppendAccessor(glb, Bytes(j1.data(), 2 * j1.size()), 5123, "VEC4", v_count);
  attributes["WEIGHTS_1"] =
      AppendAccessor(glb, Bytes(w1.data(), 2 * w1.size()), 5123, "VEC4", v_count, true);
  auto character = Load(BuildGlb(glb));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const MeshArrays& a = character->primitives[0].arrays;
  ASSERT_EQ(a.influences, 8u);
  for (std::size_t v = 0; v < v_count; ++v) {
    double w[8];
    double sum = 0;
    for (int k = 0; k < 4; ++k) {
      w[k] = w0[4 * v + static_cast<std::size_t>(k)] / 255.0;
      w[4 + k] = w1[4 * v + static_cast<std::size_t>(k)] / 65535.0;
    }
    for (double x : w) sum += x;
    for (int k = 0; k < 8; ++k) {
      const std::size_t i = 8 * v + static_cast<std::size_t>(k);
      ASSERT_NEAR(a.weights[i], w[k] / sum, 1.2e-7) << "vertex " << v << " influence " << k;
      ASSERT_EQ(a.joints[i], k < 4 ? j0[4 * v + static_cast<std::size_t>(k)]
                                   : j1[4 * v + static_cast<std::size_t>(k - 4)]);
    }
  }
  auto mesh = Mesh::Create(a);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
}

// Rotation keys stored as normalized SHORT and BYTE convert per the spec:
// max(c / 32767, -1) and max(c / 127, -1).
TEST(GltfImportTest, NormalizedIntegerRotationKeysConvertPerSpec) {
  REQUIRE_ASSET("RiggedSimple.glb");
  Glb glb = ParseGlb(ReadBytes(AssetPath("RiggedSimple.glb")));
  json& animation = glb.json["animations"][0];
  std::size_t channel = 0;
  while (animation["channels"][channel]["target"]["path"] != "rotation") ++channel;
  json& sampler = animation["samplers"][animation["channels"][channel]["sampler"].get<size_t>()];
  const std::vector<double> values = ReadAccessor(glb, sampler["output"]);
  std::vector<int16_t> shorts;
  std::vector<int8_t> bytes;
  for (double v : values) {
    shorts.push_back(static_cast<int16_t>(std::lround(v * 32767)));
    bytes.push_back(static_cast<int8_t>(std::lround(v * 127)));
  }
  shorts[0] = -32768;  // the spec's clamp: -32768 / 32767 < -1 reads as -1
  bytes[1] = -128;
  const std::size_t keys = values.size() / 4;
  for (auto [component_type, data] : {std::pair{5122, Bytes(shorts.data(), 2 * shorts.size())},
                                      std::pair{5120, Bytes(bytes.data(), bytes.size())}}) {
    Glb edited = glb;
    edited.json["animations"][0]["samplers"]
               [animation["channels"][channel]["sampler"].get<size_t>()]["output"] =
        AppendAccessor(edited, data, component_type, "VEC4", keys, true);
    auto character = Load(BuildGlb(edited));
    ASSERT_TRUE(character.ok()) << character.status().ToString();
    const std::vector<float>& got = character->clips[0].channels[channel].values;
    ASSERT_EQ(got.size(), values.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
      const double expected = component_type == 5122 ? std::max(shorts[i] / 32767.0, -1.0)
                                                     : std::max(bytes[i] / 127.0, -1.0);
      ASSERT_NEAR(got[i], expected, 1e-7) << component_type << " value " << i;
    }
  }
}

// Positions and normals interleaved in one bufferView with byteStride 24 read the same as
// the tightly packed originals; an accessor without a bufferView is zeros (spec), which for
// normals the engine's validator refuses, named with the primitive.
TEST(GltfImportTest, InterleavedAttributesAndAccessorWithoutBufferView) {
  REQUIRE_ASSET("RiggedSimple.glb");
  Glb glb = ParseGlb(ReadBytes(AssetPath("RiggedSimple.glb")));
  auto original = Load(BuildGlb(glb));
  ASSERT_TRUE(original.ok()) << original.status().ToString();
  const MeshArrays& o = original->primitives[0].arrays;
  std::vector<float> interleaved;
  for (std::size_t v = 0; v < o.vertex_count; ++v) {
    for (int c = 0; c < 3; ++c) interleaved.push_back(o.positions[3 * v + c]);
    for (int c = 0; c < 3; ++c) interleaved.push_back(o.normals[3 * v + c]);
  }
  const int view = AppendBufferView(glb, Bytes(interleaved.data(), 4 * interleaved.size()));
  glb.json["bufferViews"][view]["byteStride"] = 24;
  json& attributes = glb.json["meshes"][0]["primitives"][0]["attributes"];
  for (const char* name : {"POSITION", "NORMAL"}) {
    json& accessor = glb.json["accessors"][attributes[name].get<std::size_t>()];
    accessor["bufferView"] = view;
    accessor["byteOffset"] = std::string(name) == "NORMAL" ? 12 : 0;
  }
  auto strided = Load(BuildGlb(glb));
  ASSERT_TRUE(strided.ok()) << strided.status().ToString();
  EXPECT_EQ(strided->primitives[0].arrays.positions, o.positions);
  EXPECT_EQ(strided->primitives[0].arrays.normals, o.normals);

  glb.json["accessors"][attributes["NORMAL"].get<std::size_t>()].erase("bufferView");
  auto zeros = Load(BuildGlb(glb));
  ASSERT_FALSE(zeros.ok());
  EXPECT_EQ(zeros.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(zeros.status().message().find("meshes[0].primitives[0]: normals[vertex 0] is the zero"),
            std::string::npos)
      << zeros.status().message();
}

// A weights channel of a node whose mesh has no morph targets animates nothing: skipped
// without an error. Two nodes
// instancing the skinned mesh give two primitives; a primitive without joints is not one.
TEST(GltfImportTest, WeightsChannelsIgnoredEverySkinnedNodeCounted) {
  REQUIRE_ASSET("RiggedSimple.glb");
  Glb glb = ParseGlb(ReadBytes(AssetPath("RiggedSimple.glb")));
  json& animation = glb.json["animations"][0];
  animation["channels"].push_back({{"sampler", 0}, {"target", {{"node", 4}, {"path", "weights"}}}});
  glb.json["nodes"].push_back({{"mesh", 0}, {"skin", 0}});
  glb.json["nodes"][5]["children"].push_back(glb.json["nodes"].size() - 1);
  json rigid = glb.json["meshes"][0]["primitives"][0];
  rigid["attributes"].erase("JOINTS_0");
  rigid["attributes"].erase("WEIGHTS_0");
  glb.json["meshes"][0]["primitives"].push_back(rigid);
  auto character = Load(BuildGlb(glb));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  EXPECT_EQ(character->clips[0].channels.size(), 12u);
  ASSERT_EQ(character->primitives.size(), 2u);
  EXPECT_EQ(character->primitives[0].node, 4);
  EXPECT_EQ(character->primitives[1].node, 6);
  EXPECT_EQ(character->primitives[0].name, "Cylinder.001/0");
}

}  // namespace
}  // namespace skinserve::testing
