// skinserve-test-scene: writes one of the hand-made test characters (test_scenes.h) as a
// GLB, for the command-line end-to-end tests (tests/render/animate-e2e-test.sh), and prints
// its primitives (skinned and rigid): "<vertices> vertices in <n> primitives: <name> ...".
// usage: skinserve-test-scene several-primitives|two-skins|moving-parent|rigid-parts|
//        quantized|sparse|walking-face OUT.glb
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>

#include "test_scenes.h"

int main(int argc, char** argv) {
  using namespace skinserve::testing;
  if (argc != 3) {
    std::cerr << "usage: " << argv[0]
              << " several-primitives|two-skins|moving-parent|rigid-parts|quantized|sparse|"
                 "walking-face OUT.glb\n";
    return 2;
  }
  const std::string kind = argv[1];
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
  const std::vector<uint8_t> glb = WriteGlb(scene);
  std::ofstream out(argv[2], std::ios::binary);
  out.write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  out.close();
  if (!out) {
    std::cerr << argv[2] << ": cannot write\n";
    return 1;
  }
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
