#include "frames/pose_request.h"

#include <fmt/format.h>

#include <algorithm>
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

namespace {

// The clip's weights tracks for an error: "tracks[i] (group G): W weights" each.
std::string WeightsTracks(const animation::CompactClip& clip) {
  std::string out;
  std::size_t k = 0;  // weight_groups holds one entry per weights track, in track order
  for (std::size_t i = 0; i < clip.tracks.size(); ++i) {
    const animation::CompactTrack& t = clip.tracks[i];
    if (t.path != animation::TrackPath::kWeights) continue;
    const uint32_t group = k < clip.weight_groups.size() ? clip.weight_groups[k] : 0;
    out +=
        fmt::format("{}tracks[{}] (group {}): {} weights", k == 0 ? "" : ", ", i, group, t.width);
    ++k;
  }
  return out;
}

}  // namespace

Status PoseEvaluator::Check(const v1::SkinRequest& request, const animation::AnimationStore& store,
                            uint32_t mesh_joints, uint32_t mesh_morph_targets) {
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
  if (Status s = CheckMorph(request, mesh_morph_targets); !s.ok()) {
    Release();
    return s;
  }
  return Status::Ok();
}

Status PoseEvaluator::CheckMorph(const v1::SkinRequest& request, uint32_t mesh_morph_targets) {
  morph_.clear();
  // A mesh without morph targets has nothing to morph: a clip's weights tracks drive other
  // meshes then (a glTF clip keys the weights of every morphed node of the character).
  if (mesh_morph_targets == 0) return Status::Ok();
  int first = -1;  // the first layer whose clip has weights tracks
  for (std::size_t i = 0; i < clips_.size(); ++i) {
    const animation::CompactClip& clip = *clips_[i];
    if (clip.weight_count == 0) continue;
    if (first < 0) first = static_cast<int>(i);
    if (clip.weight_count != mesh_morph_targets) {
      return InvalidArgument(fmt::format(
          "pose.layers[{}].clip_id '{}' samples {} morph weights (weights {}); mesh {} has {} "
          "morph targets: a clip's weights tracks give the mesh's targets in order",
          i, clip.id, clip.weight_count, WeightsTracks(clip), request.mesh_id(),
          mesh_morph_targets));
    }
  }
  if (first < 0) return Status::Ok();  // no weights tracks: the request's morph weights
  if (request.morph_targets_size() > 0 || request.morph_weights_size() > 0) {
    return InvalidArgument(fmt::format(
        "morph_targets / morph_weights are set ({} / {} entries) and pose.layers[{}].clip_id "
        "'{}' has weights tracks: the server applies the clip's morph weights; send no "
        "morph_targets / morph_weights, or upload the clip without its weights tracks",
        request.morph_targets_size(), request.morph_weights_size(), first,
        clips_[static_cast<std::size_t>(first)]->id));
  }
  return EvaluateMorph();
}

Status PoseEvaluator::EvaluateMorph() {
  const std::size_t count = clips_.size();
  if (check_morph_.size() < count) check_morph_.resize(count);
  morph_layers_.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const LayerInput& in = inputs_[i];
    check_morph_[i].resize(clips_[i]->weight_count);
    const animation::MorphSamplingJob sampling{
        .clip = clips_[i].get(),
        .time = in.time,
        .mode = in.loop ? animation::TimeMode::kLoop : animation::TimeMode::kClamp,
        .morph_weights = check_morph_[i]};
    if (Status s = sampling.Run(); !s.ok()) {
      return Status(s.code(), fmt::format("pose.layers[{}]: {}", i, s.message()));
    }
    morph_layers_[i] = {
        .weight = in.weight, .additive = in.additive, .morph_weights = check_morph_[i]};
  }
  // Sized by the first clip with weights tracks (all such clips have the mesh's count).
  std::size_t targets = 0;
  for (std::size_t i = 0; i < count; ++i) targets = std::max(targets, check_morph_[i].size());
  morph_.resize(targets);
  return animation::BlendMorphWeights(morph_layers_, morph_);
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
