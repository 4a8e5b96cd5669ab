#include "pose_workload.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/synthetic_rig.h"
#include "skinserve/reference/pose_reference.h"

namespace skinserve::load {

float PoseWorkload::ClipTime(uint64_t frame) const {
  return static_cast<float>((static_cast<double>(frame % (2 * lap_frames)) + 0.5) / kPoseFps);
}

double PoseWorkload::ReferenceTime(uint64_t frame) const {
  double t = ClipTime(frame);  // what the server is sent, then looped as the server loops
  t -= duration * std::floor(t / duration);
  return t;
}

std::vector<double> PoseWorkload::ReferencePalette(uint64_t frame) const {
  const double t = ReferenceTime(frame);
  if (gltf)
    return gltf_reference::RefPalette(gltf->character, &gltf->character.clips[gltf->clip], t);
  return ReferencePosePalette(skeleton, clip, t);
}

double PoseWorkload::ErrorScale() const {
  return std::max(1.0, double{max_error_mm} / animation::kDefaultMaxErrorMm);
}

void SetLap(PoseWorkload* pose) {
  pose->lap_frames =
      std::max<uint64_t>(1, static_cast<uint64_t>(std::floor(pose->duration * kPoseFps)));
}

std::shared_ptr<PoseWorkload> MakePoseWorkload(uint32_t joints, uint64_t seed) {
  auto pose = std::make_shared<PoseWorkload>();
  animation::SyntheticRig rig = animation::MakeSyntheticRig(joints, static_cast<uint32_t>(seed));
  pose->skeleton = std::move(rig.skeleton);
  pose->clip = std::move(rig.clip);
  pose->label = "synthetic";
  pose->duration = pose->clip.duration;
  SetLap(pose.get());
  return pose;
}

Status UploadPose(client::SkinClient& client, PoseWorkload* pose, bool tell) {
  auto skeleton = client.UploadSkeleton(pose->skeleton);
  if (!skeleton.ok()) {
    return Status(skeleton.status().code(),
                  fmt::format("--animate: skeleton: {}", skeleton.status().message()));
  }
  pose->skeleton_id = skeleton->skeleton_id();
  auto clip = client.UploadClip(pose->clip, pose->skeleton_id, pose->max_error_mm);
  if (!clip.ok()) {
    return Status(clip.status().code(),
                  fmt::format("--animate: clip '{}': {}", pose->label, clip.status().message()));
  }
  pose->clip_id = clip->clip_id();
  if (!tell) return Status::Ok();
  fmt::print(stderr,
             "note: --animate: skeleton {:.8}...: {} joints; clip '{}' {:.8}...: {} tracks, "
             "{:.2f} s, {} bytes stored to {} mm ({} float bytes uploaded)\n",
             pose->skeleton_id, pose->skeleton.joint_count(), pose->label, pose->clip_id,
             pose->clip.tracks.size(), pose->clip.duration, clip->bytes(), clip->max_error_mm(),
             clip->raw_bytes());
  return Status::Ok();
}

FramePose::FramePose(const PoseWorkload& pose) : pose_(&pose) {
  layer_.clip_id = pose.clip_id;
  layer_.weight = 1;
  layer_.loop = true;
}

client::Pose FramePose::operator()(uint64_t frame) {
  layer_.time = pose_->ClipTime(frame);
  return {pose_->skeleton_id, std::span<const client::PoseLayer>(&layer_, 1)};
}

}  // namespace skinserve::load
