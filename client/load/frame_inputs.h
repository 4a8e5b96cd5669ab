// What each request of a load run carries besides its shape: a frame's palettes and morph
// weights (a crowd's instance after instance), and a tick's characters, each with its own
// mesh, palettes, weights and range of the stream's region.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pose_workload.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/client/tick.h"
#include "workload.h"

namespace skinserve::load {

// Frame f's palette for a request: with K instances, K palettes back to back, instance k
// posed as frame f + k of the workload (so that a crowd's characters differ). Returns a
// view valid until the next call; the buffer keeps its capacity from frame to frame.
class FramePalette {
 public:
  FramePalette(const Workload& workload, uint32_t instances);
  std::span<const float> operator()(uint64_t frame);

 private:
  const Workload* workload_;
  uint32_t instances_;
  std::vector<float> buffer_;
};

// Frame f's morph weights per instance of a crowd: instance k takes the workload's frame
// f + k, as its palette does. The buffer keeps its capacity from frame to frame.
class FrameMorph {
 public:
  FrameMorph(const Workload& workload, uint32_t instances);
  std::span<const std::vector<MorphWeight>> operator()(uint64_t frame);

 private:
  const Workload* workload_;
  std::vector<std::vector<MorphWeight>> buffer_;
};

// A mesh the run skins: its workload (for the reference checks) and its id on the server.
struct UploadedMesh {
  const Workload* workload = nullptr;
  std::string mesh_id;
};

// What every character of a stream's ticks asks besides its mesh and palette (the run's
// backend, encoding, crowd size; the workload's normals, tangents and method).
struct TickShape {
  std::string backend;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  uint32_t instances = 1;
};

// Fills tick f: character c skins meshes[c] with its workload's palettes of frame f (a
// crowd's instance k those of f + k), or its pose of frame f (--animate), and weights. With a
// region, character c is written at region.offset + c * character_stride. The views it adds stay
// valid until the next call.
class TickFiller {
 public:
  TickFiller(const std::vector<UploadedMesh>& meshes, const TickShape& shape,
             const client::RegionOutput& region, uint64_t character_stride);
  void operator()(uint64_t frame, client::Tick* tick);

 private:
  const std::vector<UploadedMesh>& meshes_;
  std::vector<client::SkinOptions> options_;  // per character, its morph weights set per tick
  std::vector<FramePalette> palettes_;
  std::vector<FrameMorph> morphs_;
  std::vector<std::optional<FramePose>> poses_;  // --animate: per character
};

}  // namespace skinserve::load
