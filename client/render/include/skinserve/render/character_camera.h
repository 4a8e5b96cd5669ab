// The camera for a glTF character's frames: one for the whole clip, framing every part of
// the character at every pose it takes, so that no limb leaves the image and motion shows
// as motion, not as reframing.
#pragma once

#include <span>
#include <vector>

#include "skinserve/character/character_mesh.h"
#include "skinserve/model/status.h"
#include "skinserve/render/camera.h"

namespace skinserve::render {

// Skins every mesh at every pose here, in double (the box is in the same space as the
// server's output), and frames the box around all of them. INVALID_ARGUMENT for no mesh
// or no pose; errors from the palettes pass through.
Result<Camera> CharacterCamera(const Character& character, std::span<const CharacterMesh> meshes,
                               std::span<const Pose> poses, int width, int height,
                               const CameraOptions& options = {});

// The poses CharacterCamera needs for frames 0..frames-1 at `fps` of `clip`: at most
// `count` of them, evenly spread, the last frame always included.
std::vector<Pose> ClipPoses(const Character& character, const AnimationClip& clip, double fps,
                            uint64_t frames, std::size_t count = 32);

}  // namespace skinserve::render
