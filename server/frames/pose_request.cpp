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

Status PoseEvaluator::CheckLayer(const v1::PoseLayer& layer, std::size_t i,
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
  if (clips_[i]->joint_count != skeleton_->joint_count()) {
    return InvalidArgument(fmt::format(
        "{}.clip_id '{}' was built for a skeleton of {} joints; pose.skeleton_id has {}", field,
        layer.clip_id(), clips_[i]->joint_count, skeleton_->joint_count()));
  }
  inputs_[i] = {
      .time = layer.time(), .weight = weight, .additive = layer.additive(), .loop = layer.loop()};
  return Status::Ok();
}

Status PoseEvaluator::Check(const v1::SkinRequest& request, const animation::AnimationStore& store,
                            uint32_t mesh_joints) {
  Release();  // what an earlier frame held, should it have failed after its Check
  if (Status s = CheckPoseShape(request); !s.ok()) return s;
  const v1::Pose& pose = request.pose();
  skeleton_ = store.FindSkeleton(pose.skeleton_id());
  if (skeleton_ == nullptr) {
    return NotFound(
        fmt::format("pose.skeleton_id '{}' is not stored: upload the skeleton (UploadSkeleton)",
                    pose.skeleton_id()));
  }
  if (const uint32_t entries = skeleton_->palette_size(); entries != mesh_joints) {
    Release();
    return InvalidArgument(
        fmt::format("pose.skeleton_id '{}' has a palette of {} entries; mesh {} has {} joints",
                    pose.skeleton_id(), entries, request.mesh_id(), mesh_joints));
  }
  const auto count = static_cast<std::size_t>(pose.layers_size());
  clips_.resize(count);
  inputs_.resize(count);
  double normal_weights = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (Status s = CheckLayer(pose.layers(static_cast<int>(i)), i, store); !s.ok()) {
      Release();
      return s;
    }
    if (!inputs_[i].additive) normal_weights += inputs_[i].weight;
  }
  if (!(normal_weights > 0)) {
    Release();
    return InvalidArgument(
        "pose.layers: the weights of the layers that are not additive sum to 0; at least one "
        "needs weight > 0");
  }
  return Status::Ok();
}

void PoseEvaluator::Release() {
  // What the frame read is let go: a clip deleted meanwhile is not kept by this stream.
  skeleton_.reset();
  for (auto& clip : clips_) clip.reset();
}

Status PoseEvaluator::Evaluate(std::span<float> palette) {
  Status status =
      skeleton_ == nullptr ? Internal("a pose was evaluated without its Check") : Compute(palette);
  Release();
  return status;
}

Status PoseEvaluator::SampleLayer(std::size_t i) {
  const animation::CompactClip& clip = *clips_[i];
  const LayerInput& in = inputs_[i];
  layer_poses_[i].resize(skeleton_->joint_count());
  layer_morph_[i].resize(clip.weight_count);
  const animation::SamplingJob sampling{
      .skeleton = skeleton_.get(),
      .clip = &clip,
      .time = in.time,
      .mode = in.loop ? animation::TimeMode::kLoop : animation::TimeMode::kClamp,
      .output = layer_poses_[i],
      .morph_weights = layer_morph_[i],
      .context = &contexts_[i]};
  if (Status s = sampling.Run(); !s.ok()) {
    return Status(s.code(), fmt::format("pose.layers[{}]: {}", i, s.message()));
  }
  layers_[i] = {.pose = layer_poses_[i], .weight = in.weight, .additive = in.additive};
  return Status::Ok();
}

Status PoseEvaluator::Compute(std::span<float> palette) {
  const std::size_t count = inputs_.size();
  if (layer_poses_.size() < count) layer_poses_.resize(count);
  if (layer_morph_.size() < count) layer_morph_.resize(count);
  if (contexts_.size() < count) contexts_.resize(count);
  layers_.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (Status s = SampleLayer(i); !s.ok()) return s;
  }
  const uint32_t joints = skeleton_->joint_count();
  blended_.resize(joints);
  model_.resize(joints);
  const animation::BlendingJob blending{.layers = layers_, .output = blended_};
  if (Status s = blending.Run(); !s.ok()) return s;
  const animation::LocalToModelJob to_model{
      .skeleton = skeleton_.get(), .local = blended_, .model = model_};
  if (Status s = to_model.Run(); !s.ok()) return s;
  const animation::PaletteJob palette_job{
      .skeleton = skeleton_.get(), .model = model_, .palette = palette};
  return palette_job.Run();
}

}  // namespace skinserve::server
