// The camera for a glTF character's frames: framing its rest pose, skinned here, so that
// every frame of every clip is seen from the same place.
#pragma once

#include "skinserve/core/character/character.h"
#include "skinserve/core/status.h"
#include "skinserve/render/camera.h"

namespace skinserve::render {

// Skins `primitive` at the character's rest pose with the float64 reference (the box is in
// the same space as the server's output) and frames its bounding box. Errors from the
// palette or the mesh's validation pass through.
Result<Camera> RestPoseCamera(const Character& character, const SkinnedPrimitive& primitive,
                              int width, int height, const CameraOptions& options = {});

}  // namespace skinserve::render
