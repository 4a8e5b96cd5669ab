// `skinserve-cli animate`, with and without --on-server, against a real server on loopback:
// every vertex of every OBJ frame it writes is checked against a float64 evaluation of the
// character at that frame's time, independent of the product (test_scenes.h SceneFrame for
// the hand-made characters, gltf_test_support's RefPalette and RefSkin for CesiumMan: the
// test's own glTF reading, slerp, hierarchy and skinning). The characters cover a skin
// whose joints hang under an armature node (CesiumMan, with STEP channels), two skins, rigid
// parts (a mesh of rigid parts alone: a skeleton with no skin), an animated node above the
// skeleton, morph targets on a rigid head (WalkingFace) and KHR_mesh_quantization
// (dequantized by a rigid node's transform or the inverse binds). Frames run past the clip's
// end (clamped).
//
// Tolerances, per vertex:
//  - palettes sampled by the client: 1e-5 * (1 + the frame's largest |coordinate|), as
//    walking_face_test (float32 sampling and skinning of the exact channels);
//  - --on-server: 2e-5 + 3e-4 * (|rest| + |posed|), the pose tests' bound
//    (pose_service_test.cpp): the server samples the compact clip, whose joints are within
//    0.01 mm + 1e-4 relative and whose rotations within 7.5e-5 rad a key of the uploaded
//    channels (docs/serving/animation.md#uploads), then skins in float32. A frame a tenth of
//    a second off misses by centimetres.
// The server is sent each frame's time as float32: its reference is taken at that time.
// The rest stream is float32 (--rest-encoding): the quantized one's error is not the pose's.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "gltf_test_support.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "test_scenes.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr double kFps = 10;

// Every vertex of an OBJ frame (meshes in order, each mesh's vertices), at clip time t.
using Reference = std::function<std::vector<double>(double t)>;

// The character's OBJ vertices in order: its meshes one after another (as `animate`
// writes them), each part where the importer put it.
Reference SceneReference(const Scene& scene, const std::string& path) {
  auto character = LoadGltfFile(path);
  EXPECT_TRUE(character.ok()) << character.status().ToString();
  auto meshes = CharacterMeshes(*character);
  EXPECT_TRUE(meshes.ok()) << meshes.status().ToString();
  const std::vector<ScenePrimitiveRef> prims = SkinnedPrimitives(scene);
  EXPECT_EQ(prims.size(), character->primitives.size());
  for (std::size_t i = 0; i < prims.size() && i < character->primitives.size(); ++i) {
    EXPECT_EQ(character->primitives[i].node, prims[i].node) << i;
  }
  return [scene, prims, meshes = *meshes](double t) {
    std::vector<double> out;
    for (const CharacterMesh& mesh : meshes) {
      const std::size_t first = out.size();
      out.resize(first + 3ull * mesh.arrays.vertex_count);
      for (const PrimitiveSpan& part : mesh.parts) {
        const RefFrame f = SceneFrame(scene, prims[static_cast<std::size_t>(part.primitive)], t);
        std::copy(f.positions.begin(), f.positions.end(),
                  out.begin() + static_cast<std::ptrdiff_t>(first + 3ull * part.first_vertex));
      }
    }
    return out;
  };
}

Reference AssetReference(const std::string& path) {
  const RefCharacter ref = ReadReference(ParseGlb(ReadBytes(path)));
  return [ref](double t) {
    return RefSkin(ref.primitive, RefPalette(ref, &ref.clips.at(0), t)).positions;
  };
}

std::vector<double> ReadObjVertices(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::vector<double> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) != 0) continue;
    std::istringstream fields(line.substr(2));
    double x, y, z;
    fields >> x >> y >> z;
    out.insert(out.end(), {x, y, z});
  }
  return out;
}

// `skinserve-cli animate` into `out`; its exit status (stdout and stderr into out.log).
int Animate(const std::string& target, const std::string& file, const std::string& out,
            const std::string& extra) {
  const std::string command = std::string(SKINSERVE_CLI_BINARY) + " --target " + target +
                              " animate " + file +
                              " --fps 10 --backend serial --rest-encoding float32 --out " + out +
                              extra + " > " + out + ".log 2>&1";
  return WEXITSTATUS(std::system(command.c_str()));
}

// Every frame of `dir` against `reference`; the worst error over its bound.
double ExpectFramesNear(const std::string& dir, uint64_t frames, const Reference& reference,
                        bool on_server, const std::vector<float>& rest) {
  double worst = 0;
  for (uint64_t f = 0; f < frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%04llu.obj", static_cast<unsigned long long>(f));
    const std::vector<double> got = ReadObjVertices(dir + name);
    const double exact = static_cast<double>(f) / kFps;
    const std::vector<double> want = reference(on_server ? static_cast<float>(exact) : exact);
    EXPECT_EQ(got.size(), want.size()) << dir << name;
    if (got.size() != want.size() || rest.size() != want.size()) return INFINITY;
    double largest = 0;
    for (double w : want) largest = std::max(largest, std::fabs(w));
    for (std::size_t v = 0; v < want.size() / 3; ++v) {
      double d2 = 0, rest2 = 0, posed2 = 0;
      for (std::size_t i = 3 * v; i < 3 * v + 3; ++i) {
        d2 += (got[i] - want[i]) * (got[i] - want[i]);
        rest2 += double{rest[i]} * rest[i];
        posed2 += want[i] * want[i];
      }
      const double bound =
          on_server ? 2e-5 + 3e-4 * (std::sqrt(rest2) + std::sqrt(posed2)) : 1e-5 * (1 + largest);
      worst = std::max(worst, std::sqrt(d2) / bound);
      if (std::sqrt(d2) > bound) {
        ADD_FAILURE() << dir << name << ": vertex " << v << " off by " << std::sqrt(d2)
                      << " (bound " << bound << ")";
        return worst;
      }
    }
  }
  return worst;
}

// The rest positions in the OBJ's order (for the bound's |rest|).
std::vector<float> RestPositions(const std::string& path) {
  auto character = LoadGltfFile(path);
  auto meshes = CharacterMeshes(*character);
  std::vector<float> rest;
  for (const CharacterMesh& mesh : *meshes) {
    rest.insert(rest.end(), mesh.arrays.positions.begin(), mesh.arrays.positions.end());
  }
  return rest;
}

void CheckCharacter(const TestServer& t, const std::string& label, const std::string& path,
                    double seconds, const Reference& reference) {
  SCOPED_TRACE(label);
  const uint64_t frames = static_cast<uint64_t>(std::llround(seconds * kFps));
  const std::string base =
      ::testing::TempDir() + "animate-" + std::to_string(getpid()) + "-" + label;
  const std::string extra = " --seconds " + std::to_string(seconds);
  const std::vector<float> rest = RestPositions(path);
  for (const bool on_server : {false, true}) {
    const std::string out = base + (on_server ? "-server" : "-client");
    ASSERT_EQ(Animate(t.target, path, out, extra + (on_server ? " --on-server" : "")), 0)
        << "see " << out << ".log";
    const double worst = ExpectFramesNear(out, frames, reference, on_server, rest);
    ::testing::Test::RecordProperty(label + (on_server ? " server" : " client"),
                                    std::to_string(worst));
    std::printf("%s %s: worst error %.3g of its bound over %llu frames\n", label.c_str(),
                on_server ? "--on-server" : "client palettes", worst,
                static_cast<unsigned long long>(frames));
    std::filesystem::remove_all(out);
    std::filesystem::remove(out + ".log");
  }
}

std::string WriteScene(const Scene& scene, const std::string& label) {
  const std::string path =
      ::testing::TempDir() + "animate-" + std::to_string(getpid()) + "-" + label + ".glb";
  const std::vector<uint8_t> glb = WriteGlb(scene);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  return path;
}

TEST(AnimateOnServerTest, EveryFrameMatchesTheFloat64CharacterWithAndWithoutOnServer) {
  REQUIRE_ASSET("CesiumMan.glb");
  TestServer t;
  CheckCharacter(t, "CesiumMan", AssetPath("CesiumMan.glb"), 2.3,
                 AssetReference(AssetPath("CesiumMan.glb")));
  const std::pair<const char*, Scene> scenes[] = {{"RigidParts", RigidParts()},
                                                  {"TwoSkins", TwoSkins()},
                                                  {"MovingParent", MovingParent()},
                                                  {"WalkingFace", WalkingFace()},
                                                  {"Quantized", Quantized()}};
  for (const auto& [label, scene] : scenes) {
    const std::string path = WriteScene(scene, label);
    CheckCharacter(t, label, path, scene.clip.duration + 0.3, SceneReference(scene, path));
    std::filesystem::remove(path);
  }
  // `skinserve-cli stats` prints the animation store GetServerStats reports.
  auto stats = t.client->GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_GE(stats->clips(), 6u);  // one per character at least
  const std::string log = ::testing::TempDir() + "animate-stats-" + std::to_string(getpid());
  ASSERT_EQ(
      std::system((std::string(SKINSERVE_CLI_BINARY) + " --target " + t.target + " stats > " + log)
                      .c_str()),
      0);
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ostringstream line;
  line << "animation: skeletons " << stats->skeletons() << " and clips " << stats->clips()
       << " using " << stats->clip_bytes() << " of " << stats->clip_budget_bytes() << " bytes\n";
  EXPECT_NE(text.find(line.str()), std::string::npos) << text;
  std::filesystem::remove(log);
}

TEST(AnimateOnServerTest, AClipTheFileLacksIsNamedBeforeAnythingIsUploaded) {
  REQUIRE_ASSET("CesiumMan.glb");
  TestServer t;
  const std::string out = ::testing::TempDir() + "animate-bad-" + std::to_string(getpid());
  EXPECT_NE(Animate(t.target, AssetPath("CesiumMan.glb"), out, " --on-server --clip Nope"), 0);
  std::ifstream log(out + ".log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("--clip 'Nope'"), std::string::npos) << text;
  EXPECT_NE(text.find("'Anim_0'"), std::string::npos) << text;
  auto stats = t.client->GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->meshes(), 0u);
  std::filesystem::remove(out + ".log");
}

}  // namespace
}  // namespace skinserve::testing
