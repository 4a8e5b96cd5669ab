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
//
// Morph weights: the engine checks a frame's morph weights when it is submitted, so the
// clips' weights tracks are sampled and blended in Check (cheap: a few floats a layer),
// joints stay on the compute thread. Layers are blended as the joints are (BlendMorphWeights:
// normal layers' weights normalised by their sum, additive ones added times their weight; a
// clip without weights tracks contributes zeros). A frame whose clips have weights tracks
// takes them as its morph weights (their count must be the mesh's morph target count); it
// may not set morph_targets / morph_weights too. A mesh without morph targets leaves them
// out (they drive another mesh of the character).
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
  // size other than the mesh's `mesh_joints`, a clip's morph weights other than the mesh's
  // `mesh_morph_targets`, weights tracks with morph_targets / morph_weights set; NOT_FOUND
  // naming the skeleton or clip id not stored) and keeps what Evaluate needs: the skeleton
  // and clips (held until Evaluate or Release) and each layer's time, weight and mode
  // (`request` may change meanwhile). Samples and blends the clips' morph weights (below).
  Status Check(const v1::SkinRequest& request, const animation::AnimationStore& store,
               uint32_t mesh_joints, uint32_t mesh_morph_targets);
  // After a Check that returned OK: the blended morph weights of the clips' weights tracks,
  // one per mesh morph target; empty when no layer's clip has weights tracks.
  std::span<const float> morph_weights() const { return morph_; }
  // After a Check that returned OK: writes the palette, 12 floats an entry, into `palette`
  // (12 * mesh_joints floats), then lets go of the skeleton and clips.
  Status Evaluate(std::span<float> palette);
  // Lets go of what Check held (its frame failed before Evaluate).
  void Release();

 private:
  // Looks up and checks layer i's clip and fields into clips_[i] and inputs_[i].
  Status CheckLayer(const v1::PoseLayer& layer, std::size_t i,
                    const animation::AnimationStore& store);
  // The layers' morph weights (their clips' weights tracks) checked against the mesh,
  // sampled and blended into morph_.
  Status CheckMorph(const v1::SkinRequest& request, uint32_t mesh_morph_targets);
  Status EvaluateMorph();
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
  // Check's morph weights: each layer's sampled (empty for a clip without weights tracks),
  // and blended.
  std::vector<std::vector<float>> check_morph_;
  std::vector<animation::BlendLayer> morph_layers_;
  std::vector<float> morph_;
};

}  // namespace skinserve::server
