#include "frames/pose_request.h"

#include <fmt/format.h>

#include <cmath>

#include "skinserve/animation/local_to_model_job.h"
#include "skinserve/animation/palette_job.h"
#include "skinserve/animation/sampling_job.h"

namespace skinserve::server {
namespace {

using animation::kMaxBlendLayers;

// What a pose request must not combine, before anything is looked up.
Status CheckPoseShape(const v1::SkinRequest& request) {
  const v1::Pose& pose = request.pose();
  if (!request.palette().empty()) {
    return InvalidArgument(
        "palette and pose are both set; a frame carries one of them (a pose is turned into the "
        "palette by the server)");
  }
  if (request.instances() > 1) {
    return InvalidArgument(fmt::format(
        "pose is set with instances = {}; a pose is one instance's (send a crowd's palettes)",
        request.instances()));
  }
  if (pose.layers_size() == 0 || pose.layers_size() > static_cast<int>(kMaxBlendLayers)) {
    return InvalidArgument(fmt::format("pose.layers has {} entries; 1..{} are supported",
                                       pose.layers_size(), kMaxBlendLayers));
  }
  return Status::Ok();
}

}  // namespace

Status PoseEvaluator::SampleLayer(const v1::PoseLayer& layer, std::size_t i,
                                  const animation::AnimationStore& store) {
  const std::string field = fmt::format("pose.layers[{}]", i);
  if (!std::isfinite(layer.time())) {
    return InvalidArgument(
        fmt::format("{}.time = {}; must be finite (seconds)", field, layer.time()));
  }
  const float weight = layer.has_weight() ? layer.weight() : 1.0f;
  if (!std::isfinite(weight) || weight < 0) {
    return InvalidArgument(fmt::format("{}.weight = {}; must be finite and >= 0", field, weight));
  }
  clips_[i] = store.FindClip(layer.clip_id());
  if (clips_[i] == nullptr) {
    return NotFound(fmt::format("{}.clip_id '{}' is not stored: upload the clip (UploadClip)",
                                field, layer.clip_id()));
  }
  const animation::CompactClip& clip = *clips_[i];
  if (clip.joint_count != skeleton_->joint_count()) {
    return InvalidArgument(fmt::format(
        "{}.clip_id '{}' was built for a skeleton of {} joints; pose.skeleton_id has {}", field,
        layer.clip_id(), clip.joint_count, skeleton_->joint_count()));
  }
  layer_poses_[i].resize(skeleton_->joint_count());
  layer_morph_[i].resize(clip.weight_count);
  const animation::SamplingJob sampling{
      .skeleton = skeleton_.get(),
      .clip = &clip,
      .time = layer.time(),
      .mode = layer.loop() ? animation::TimeMode::kLoop : animation::TimeMode::kClamp,
      .output = layer_poses_[i],
      .morph_weights = layer_morph_[i],
      .context = &contexts_[i]};
  if (Status s = sampling.Run(); !s.ok()) {
    return Status(s.code(), fmt::format("{}: {}", field, s.message()));
  }
  layers_[i] = {.pose = layer_poses_[i], .weight = weight, .additive = layer.additive()};
  return Status::Ok();
}

Status PoseEvaluator::Evaluate(const v1::SkinRequest& request,
                               const animation::AnimationStore& store, uint32_t mesh_joints,
                               std::vector<float>* palette) {
  Status status = Compute(request, store, mesh_joints, palette);
  // What the frame read is let go: a clip deleted meanwhile is not kept by this stream.
  skeleton_.reset();
  for (auto& clip : clips_) clip.reset();
  return status;
}

Status PoseEvaluator::Compute(const v1::SkinRequest& request,
                              const animation::AnimationStore& store, uint32_t mesh_joints,
                              std::vector<float>* palette) {
  if (Status s = CheckPoseShape(request); !s.ok()) return s;
  const v1::Pose& pose = request.pose();
  skeleton_ = store.FindSkeleton(pose.skeleton_id());
  if (skeleton_ == nullptr) {
    return NotFound(
        fmt::format("pose.skeleton_id '{}' is not stored: upload the skeleton (UploadSkeleton)",
                    pose.skeleton_id()));
  }
  if (skeleton_->palette_size() != mesh_joints) {
    return InvalidArgument(
        fmt::format("pose.skeleton_id '{}' has a palette of {} entries; mesh {} has {} joints",
                    pose.skeleton_id(), skeleton_->palette_size(), request.mesh_id(), mesh_joints));
  }
  const auto count = static_cast<std::size_t>(pose.layers_size());
  clips_.resize(count);
  if (layer_poses_.size() < count) layer_poses_.resize(count);
  if (layer_morph_.size() < count) layer_morph_.resize(count);
  if (contexts_.size() < count) contexts_.resize(count);
  layers_.resize(count);
  double normal_weights = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (Status s = SampleLayer(pose.layers(static_cast<int>(i)), i, store); !s.ok()) return s;
    if (!layers_[i].additive) normal_weights += layers_[i].weight;
  }
  if (!(normal_weights > 0)) {
    return InvalidArgument(
        "pose.layers: the weights of the layers that are not additive sum to 0; at least one "
        "needs weight > 0");
  }
  const uint32_t joints = skeleton_->joint_count();
  blended_.resize(joints);
  model_.resize(joints);
  palette->resize(12ull * mesh_joints);
  const animation::BlendingJob blending{.layers = layers_, .output = blended_};
  if (Status s = blending.Run(); !s.ok()) return s;
  const animation::LocalToModelJob to_model{
      .skeleton = skeleton_.get(), .local = blended_, .model = model_};
  if (Status s = to_model.Run(); !s.ok()) return s;
  const animation::PaletteJob palette_job{
      .skeleton = skeleton_.get(), .model = model_, .palette = *palette};
  return palette_job.Run();
}

}  // namespace skinserve::server
