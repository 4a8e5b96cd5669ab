// PoseEvaluator: a frame's SkinRequest.pose turned into the skinning palette the engine
// reads, instead of a palette off the wire. Each layer's clip is sampled at its time
// (looped or clamped), the layers blended (normalised weights, shortest-path rotations,
// additive layers on top), the hierarchy composed into model space and multiplied by the
// inverse bind matrices (core/animation's jobs). One per FrameJob: its buffers are reused
// frame after frame, so a steady stream of poses allocates nothing once they have grown.
#pragma once

#include <memory>
#include <vector>

#include "skinserve/animation/animation_store.h"
#include "skinserve/animation/blending_job.h"
#include "skinserve/animation/sampling_job.h"
#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

class PoseEvaluator {
 public:
  // Checks `request`'s pose (INVALID_ARGUMENT naming the field: palette set too, a crowd,
  // layer count, a layer's time or weight, a clip built for another joint count, a palette
  // size other than the mesh's `mesh_joints`; NOT_FOUND naming the skeleton or clip id not
  // stored) and writes the palette, 12 floats an entry, into `palette` (resized).
  Status Evaluate(const v1::SkinRequest& request, const animation::AnimationStore& store,
                  uint32_t mesh_joints, std::vector<float>* palette);

 private:
  Status Compute(const v1::SkinRequest& request, const animation::AnimationStore& store,
                 uint32_t mesh_joints, std::vector<float>* palette);
  // Looks up and checks layer i's clip and fields, then samples it into layer_poses_[i].
  Status SampleLayer(const v1::PoseLayer& layer, std::size_t i,
                     const animation::AnimationStore& store);

  std::shared_ptr<const animation::Skeleton> skeleton_;
  std::vector<std::shared_ptr<const animation::CompactClip>> clips_;  // the frame's, held
  std::vector<std::vector<animation::Transform>> layer_poses_;
  std::vector<std::vector<float>> layer_morph_;
  // One per layer: the stream's next frame usually samples the same clip a little later,
  // so the key search and the decoded keys carry over (SamplingContext).
  std::vector<animation::SamplingContext> contexts_;
  std::vector<animation::BlendLayer> layers_;
  std::vector<animation::Transform> blended_;
  std::vector<animation::Affine> model_;
};

}  // namespace skinserve::server
