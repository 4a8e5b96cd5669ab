// --animate: frames that carry a pose instead of a palette (docs/serving/animation.md#pose).
// `--animate synthetic`: the synthetic mesh gets the synthetic skeleton and clip of its joint
// count (MakeSyntheticRig, deterministic from the seed). `--animate FILE.glb`: the glTF
// character's skeleton and clip (gltf_pose_workload.h). Either is uploaded once a run;
// frame f asks the server for the clip at ClipTime(f), looping, and a checked answer is
// compared with the clip evaluated in float64 (pose_check.h).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/client/pose.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/model/status.h"
#include "skinserve/reference/gltf_reference.h"

namespace skinserve::load {

// Frames of clip time per second of a pose workload (as a glTF workload's palettes).
inline constexpr double kPoseFps = 30.0;

// --animate FILE: the check's own reading of the file (gltf_reference.h, apart from the
// importer that made the skeleton and clip uploaded) and which of its clips plays.
struct GltfPoseReference {
  gltf_reference::RefCharacter character;
  std::size_t clip = 0;  // in character.clips
};

struct PoseWorkload {
  animation::Skeleton skeleton;
  animation::RawClip clip;
  // What rows say was played: "synthetic", or the glTF clip's name.
  std::string label;
  // The loop's length in the reference: the synthetic clip's, or the file's clip's (its
  // last key, read by the check's own reader).
  double duration = 1;
  std::string skeleton_id, clip_id;  // on the server (UploadPose)
  // --clip-error-mm: the bound the server stores the clip to (0: its default, 0.01 mm);
  // the check's bound grows with it (ErrorScale).
  float max_error_mm = 0;
  uint64_t lap_frames = 1;  // frames of one lap of the clip at kPoseFps
  // --animate FILE: answers are checked against the file's own channels and primitive;
  // null: against `clip` on `skeleton` and the workload's mesh (synthetic).
  std::shared_ptr<const GltfPoseReference> gltf;

  // Frame f plays the clip at ((f mod 2 laps) + 0.5) / kPoseFps s, looped: the server wraps
  // every other lap itself, the half frame keeps each time off the clip's keys (on a STEP
  // key float32 rounding may land on either side), and the time stays below two laps so
  // that float32 holds it to ~1e-7 s however long the run.
  float ClipTime(uint64_t frame) const;
  // Frame f's time as sent (float32), wrapped into [0, duration) in double as the server
  // loops it.
  double ReferenceTime(uint64_t frame) const;
  // Frame f's palette in float64 at ReferenceTime: ReferencePosePalette of the synthetic
  // clip, or RefPalette of the file's clip; 12 doubles a joint.
  std::vector<double> ReferencePalette(uint64_t frame) const;
  // The check's bound (pose_check.h) times this: max_error_mm over the default's, at least 1.
  double ErrorScale() const;
};

// The synthetic rig of `joints` joints (the synthetic mesh's) seeded from `seed`.
std::shared_ptr<PoseWorkload> MakePoseWorkload(uint32_t joints, uint64_t seed);

// Sets lap_frames from `duration` (at least one frame a lap).
void SetLap(PoseWorkload* pose);

// Uploads the rig's skeleton and clip (content-addressed: once stored, again is free) and
// keeps their ids; with `tell`, prints what went up on stderr. The server's error, naming
// what failed.
Status UploadPose(client::SkinClient& client, PoseWorkload* pose, bool tell = true);

// Frame f's pose as the client library sends it: one layer, the clip at ClipTime(f),
// weight 1, looped. The view is valid until the next call.
class FramePose {
 public:
  explicit FramePose(const PoseWorkload& pose);
  client::Pose operator()(uint64_t frame);

 private:
  const PoseWorkload* pose_;
  client::PoseLayer layer_;
};

}  // namespace skinserve::load
