// PoseEvaluator: a frame's SkinRequest.pose turned into the skinning palette the engine
// reads, instead of a palette off the wire. In two steps: Check, on the thread that
// prepares the frame, looks up and checks what is cheap to check (ids, times, weights,
// sizes) so that bad input fails before the engine with its field named, and holds the
// skeleton and clips; Evaluate, on the compute thread that then skins the frame
// (SkinJob::FillInputs), samples each layer's clip at its time (looped or clamped), blends
// the layers (normalised weights, shortest-path rotations, additive layers on top),
// composes the hierarchy into model space and multiplies by the inverse bind matrices
// (core/animation's jobs). One per FrameJob, so each frame in flight has its own scratch:
// its buffers are reused frame after frame, so a steady stream of poses allocates nothing
// once they have grown.
#pragma once

#include <memory>
#include <span>
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
  // stored) and keeps what Evaluate needs: the skeleton and clips (held until Evaluate or
  // Release) and each layer's time, weight and mode (`request` may change meanwhile).
  Status Check(const v1::SkinRequest& request, const animation::AnimationStore& store,
               uint32_t mesh_joints);
  // After a Check that returned OK: writes the palette, 12 floats an entry, into `palette`
  // (12 * mesh_joints floats), then lets go of the skeleton and clips.
  Status Evaluate(std::span<float> palette);
  // Lets go of what Check held (its frame failed before Evaluate).
  void Release();

 private:
  // Looks up and checks layer i's clip and fields into clips_[i] and inputs_[i].
  Status CheckLayer(const v1::PoseLayer& layer, std::size_t i,
                    const animation::AnimationStore& store);
  Status Compute(std::span<float> palette);
  // Samples layer i's clip into layer_poses_[i].
  Status SampleLayer(std::size_t i);

  // What Check kept of each layer.
  struct LayerInput {
    float time = 0;
    float weight = 1;
    bool additive = false;
    bool loop = false;
  };
  std::shared_ptr<const animation::Skeleton> skeleton_;
  std::vector<std::shared_ptr<const animation::CompactClip>> clips_;  // the frame's, held
  std::vector<LayerInput> inputs_;
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
