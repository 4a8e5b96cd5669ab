// The frames skinserve-gpu-region sends: one StreamSkin call with `window` frames in
// flight, each written into slot (frame % window) of a region (a GPU region or a
// shared-memory one), positions (and normals) at the region layout's offsets, in the
// plan's encoding. With more than one character a frame is a tick (SkinRequest.characters):
// character c of the slot's ticks at c * slot_bytes within it, each on its own mesh.
#pragma once

#include <functional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::gpu_region {

struct StreamPlan {
  std::vector<std::string> mesh_ids;  // one per character: one (frames) or more (ticks)
  std::string backend;
  std::string region;  // registered name
  bool gpu = false;    // a GPU region (OutputRegion.gpu)
  uint32_t frames = 1, window = 1;
  uint64_t slot_bytes = 0;  // one character's room in the region (a multiple of 64)
  bool normals = false;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  // Character c's palette in frame f, as the bytes SkinRequest.palette carries.
  std::function<const std::string&(uint32_t frame, uint32_t character)> palette;
  // Its morph target weights, sparse (a glTF character's clip); null: none.
  std::function<std::span<const MorphWeight>(uint32_t frame, uint32_t character)> morph;
  // Paced: frame f is sent at the start + f / rate, not before (0: as soon as the window
  // allows); each frame's time from its send to its answer (ms) goes to *latencies_ms when
  // it is set (with window 1 the answer is read as it comes).
  double rate = 0;
  std::vector<double>* latencies_ms = nullptr;
  uint64_t tick_bytes() const { return slot_bytes * mesh_ids.size(); }
};

// Runs the frames; `answered(frame, response)` sees each frame's answer in order (a tick's
// final part: TickAnswer's headers, each with its RegionWrite), and may check the slot's
// bytes before the frame that reuses it is sent (window 1 guarantees that). The first
// failed frame's status (or a tick's first failed character's) ends the run.
Status StreamIntoRegion(v1::Skinning::Stub& stub, const StreamPlan& plan,
                        const std::function<Status(uint32_t, const v1::SkinResponse&)>& answered);

}  // namespace skinserve::gpu_region
