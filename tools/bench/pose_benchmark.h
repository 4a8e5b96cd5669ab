// BM_Pose rows: the animation runtime's frame for one character (issue 43), beside BM_Skin.
#pragma once

namespace skinserve::bench {

// BM_Pose/<joints>: two clip layers sampled, blended (0.3 / 0.7), local-to-model and the
// palette; BM_PoseOneClip/<joints>: one layer, no blend (what ozz's 2.2 us anchor, a
// 67-joint character's SamplingJob + LocalToModelJob on one core of the VM, compares to).
// Synthetic rigs of 67 and 77 joints (skinserve/animation/synthetic_rig.h), 30 keys a
// second, the time advancing 1/60 s a frame.
void RegisterPoseBenchmarks();

}  // namespace skinserve::bench
