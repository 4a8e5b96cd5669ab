#include "skinserve/client/pose.h"

namespace skinserve::client {

void PoseToWire(const Pose& pose, v1::SkinRequest* request) {
  if (pose.empty()) {
    request->clear_pose();
    return;
  }
  v1::Pose* wire = request->mutable_pose();
  wire->set_skeleton_id(pose.skeleton_id);
  wire->clear_layers();  // keeps the layers' messages for reuse
  for (const PoseLayer& layer : pose.layers) {
    v1::PoseLayer* out = wire->add_layers();
    out->set_clip_id(layer.clip_id);
    out->set_time(layer.time);
    out->set_weight(layer.weight);
    out->set_additive(layer.additive);
    out->set_loop(layer.loop);
  }
}

}  // namespace skinserve::client
