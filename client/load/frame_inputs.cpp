#include "frame_inputs.h"

#include <algorithm>

namespace skinserve::load {

FramePalette::FramePalette(const Workload& workload, uint32_t instances)
    : workload_(&workload), instances_(std::max(instances, 1u)) {}

std::span<const float> FramePalette::operator()(uint64_t frame) {
  if (instances_ == 1) return workload_->Palette(frame);
  buffer_.clear();
  for (uint32_t k = 0; k < instances_; ++k) {
    const std::vector<float>& p = workload_->Palette(frame + k);
    buffer_.insert(buffer_.end(), p.begin(), p.end());
  }
  return buffer_;
}

FrameMorph::FrameMorph(const Workload& workload, uint32_t instances)
    : workload_(&workload), buffer_(std::max(instances, 1u)) {}

std::span<const std::vector<MorphWeight>> FrameMorph::operator()(uint64_t frame) {
  for (std::size_t k = 0; k < buffer_.size(); ++k) buffer_[k] = workload_->MorphVector(frame + k);
  return buffer_;
}

TickFiller::TickFiller(const std::vector<UploadedMesh>& meshes, const TickShape& shape,
                       const client::RegionOutput& region, uint64_t character_stride)
    : meshes_(meshes) {
  for (std::size_t c = 0; c < meshes.size(); ++c) {
    const Workload& w = *meshes[c].workload;
    client::SkinOptions options{.backend = shape.backend,
                                .want_normals = w.normals,
                                .want_tangents = w.tangents,
                                .method = w.method,
                                .encoding = shape.encoding,
                                .instances = shape.instances};
    if (region.enabled()) {
      options.output = region;
      options.output.offset = region.offset + c * character_stride;
      options.output.stride = 0;
    }
    options_.push_back(std::move(options));
    palettes_.emplace_back(w, shape.instances);
    morphs_.emplace_back(w, shape.instances);
    poses_.emplace_back();
    if (w.pose) poses_.back().emplace(*w.pose);
  }
}

void TickFiller::operator()(uint64_t frame, client::Tick* tick) {
  for (std::size_t c = 0; c < meshes_.size(); ++c) {
    const Workload& w = *meshes_[c].workload;
    client::SkinOptions& options = options_[c];
    // Morph weights: a single instance's straight from the workload, a crowd's per instance.
    if (!w.morph_weights.empty() && options.instances <= 1) {
      options.morph_weights = w.Morph(frame);
    } else if (!w.morph_weights.empty()) {
      options.instance_morph_weights = morphs_[c](frame);
    }
    if (poses_[c]) {
      tick->AddPose(meshes_[c].mesh_id, (*poses_[c])(frame), options);
    } else {
      tick->Add(meshes_[c].mesh_id, palettes_[c](frame), options);
    }
  }
}

}  // namespace skinserve::load
