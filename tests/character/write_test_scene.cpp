// skinserve-test-scene: writes one of the hand-made test characters (test_scenes.h) as a
// GLB, for the command-line end-to-end tests (tests/render/animate-e2e-test.sh), and prints
// its primitives (skinned and rigid): "<vertices> vertices in <n> primitives: <name> ...".
// usage: skinserve-test-scene several-primitives|two-skins|moving-parent|rigid-parts|
//        quantized|sparse|walking-face|tangents OUT.glb
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "tangent_scene.h"
#include "test_scenes.h"

namespace {

bool WriteFile(const char* path, const std::vector<uint8_t>& glb) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  out.close();
  if (!out) std::cerr << path << ": cannot write\n";
  return static_cast<bool>(out);
}

// The skinned character with tangents and morph tangent deltas (tangent_scene.h).
int WriteTangentScene(const char* path) {
  const skinserve::testing::TangentScene scene = skinserve::testing::MakeTangentScene();
  if (!WriteFile(path, skinserve::testing::BuildGlb(scene.glb))) return 1;
  std::size_t vertices = 0;
  for (const auto& p : scene.primitives) vertices += p.vertex_count;
  std::cout << vertices << " vertices in " << scene.primitives.size()
            << " primitives: Body/0 Hat/0\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace skinserve::testing;
  if (argc != 3) {
    std::cerr << "usage: " << argv[0]
              << " several-primitives|two-skins|moving-parent|rigid-parts|quantized|sparse|"
                 "walking-face|tangents OUT.glb\n";
    return 2;
  }
  const std::string kind = argv[1];
  if (kind == "tangents") return WriteTangentScene(argv[2]);
  Scene scene;
  if (kind == "several-primitives") {
    scene = SeveralPrimitivesOneSkin();
  } else if (kind == "two-skins") {
    scene = TwoSkins();
  } else if (kind == "moving-parent") {
    scene = MovingParent();
  } else if (kind == "rigid-parts") {
    scene = RigidParts();
  } else if (kind == "quantized") {
    scene = Quantized();
  } else if (kind == "sparse") {
    scene = Sparse();
  } else if (kind == "walking-face") {
    scene = WalkingFace();
  } else {
    std::cerr << "unknown scene '" << kind << "'\n";
    return 2;
  }
  if (!WriteFile(argv[2], WriteGlb(scene))) return 1;
  std::size_t vertices = 0;
  std::string names;
  const std::vector<ScenePrimitiveRef> primitives = SkinnedPrimitives(scene);
  for (const ScenePrimitiveRef& p : primitives) {
    vertices += scene.meshes[static_cast<std::size_t>(p.mesh)]
                    .primitives[static_cast<std::size_t>(p.primitive)]
                    .positions.size() /
                3;
    names += " " + p.name;
  }
  std::cout << vertices << " vertices in " << primitives.size() << " primitives:" << names << "\n";
  return 0;
}
