// The glTF importer from raw file bytes (GLB or JSON glTF with data: URIs). An imported
// character must be usable: every primitive goes through the engine's mesh validation, and each
// clip samples to skin palettes at its start, middle and end (a crash or a sanitizer
// report is the failure).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/model/mesh.h"

using namespace skinserve;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // No base directory: an external buffer URI must fail, never read a file of the fuzzer's.
  auto character = LoadGltfBytes(std::span<const uint8_t>(data, size), "/nonexistent");
  if (!character.ok()) return 0;
  for (const SkinnedPrimitive& primitive : character->primitives) {
    (void)Mesh::Create(primitive.arrays, MeshOptions{});
  }
  // The whole character as it travels: skinned primitives and rigid parts grouped.
  const auto meshes = CharacterMeshes(*character);
  std::vector<const AnimationClip*> clips{nullptr};  // nullptr: the rest pose
  for (const AnimationClip& clip : character->clips) clips.push_back(&clip);
  for (const AnimationClip* clip : clips) {
    for (double t : {0.0, 0.5, 1.0}) {
      const Pose pose =
          clip ? SampleClip(*character, *clip, t * clip->duration) : RestPose(*character);
      for (int skin = 0; skin < static_cast<int>(character->skins.size()); ++skin) {
        (void)SkinPalette(*character, pose, skin);
      }
      if (meshes.ok()) (void)MeshPalettes(*character, pose, *meshes);
    }
  }
  return 0;
}
