// Animation: the paper's stage 2. Sample a clip at a time, compose local transforms through
// the node hierarchy, multiply by the inverse bind matrices: the joint palette the server
// expects (12 floats per joint, row-major 3x4, see palette.h).
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/character/character.h"
#include "skinserve/model/status.h"

namespace skinserve {

// Local TRS of every node of a character, in node order.
using Pose = std::vector<CharacterNode>;

// The nodes' transforms as the file states them, with no clip applied.
Pose RestPose(const Character& character);

// `pose` with every channel of `clip` sampled at `seconds` (clamped to [0, duration]),
// per the glTF spec: LINEAR (slerp for rotations), STEP, CUBICSPLINE (Hermite, rotations
// normalised).
Pose SampleClip(const Character& character, const AnimationClip& clip, double seconds);

// palette[j] = model(skin.joints[j]) * skin.inverse_bind[j], where model() composes local
// T * R * S from the root down. The skinned mesh node's own transform is ignored, as the
// spec requires. INVALID_ARGUMENT if `skin` is out of range or the pose has the wrong size.
Result<std::vector<float>> SkinPalette(const Character& character, const Pose& pose, int skin);

// palette[k] = model(nodes[k]): the world matrices of the nodes rigid parts follow (their
// vertices are in the node's space, so their "inverse bind" is the identity).
// INVALID_ARGUMENT if a node is out of range or the pose has the wrong size.
Result<std::vector<float>> NodePalette(const Character& character, const Pose& pose,
                                       const std::vector<int>& nodes);

}  // namespace skinserve
