// Transform: a joint's local translation, rotation and scale (glTF's TRS): what sampling
// writes, blending mixes and local-to-model composes (M = T * R * S).
#pragma once

namespace skinserve::animation {

struct Transform {
  float translation[3] = {0, 0, 0};
  float rotation[4] = {0, 0, 0, 1};  // unit quaternion x y z w (glTF's order)
  float scale[3] = {1, 1, 1};
};

// 3x4 affine matrix, row-major, 12 floats (the implied last row is 0 0 0 1): the layout of
// a skinning palette entry (skinserve/model/palette.h) and of model-space matrices here.
struct Affine {
  float m[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
};

}  // namespace skinserve::animation
