// FrameJob: one frame on its way through the server. It owns the output buffers the
// engine writes into, and once the frame is done it cuts the result into response parts
// of bounded size (so no message needs more than gRPC's default 4 MiB).
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "metrics_frames.h"
#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

inline constexpr std::size_t kMaxPartPayloadBytes = 1 << 20;

class FrameJob {
 public:
  // Prepares the engine request for `request` (palette decoded, outputs allocated from
  // the mesh's size). A non-OK status means the frame failed before reaching the engine.
  Status Prepare(const v1::SkinRequest& request, const Engine& engine,
                 const std::string& default_backend, SkinRequest* engine_request);
  // Records the engine's verdict.
  void Complete(Status status, FrameTiming timing);

  bool done() const { return done_; }
  const Status& status() const { return status_; }
  uint64_t frame() const { return frame_; }
  // The next response part; false when every part has been produced.
  bool NextPart(v1::SkinResponse* part);

 private:
  uint64_t frame_ = 0;
  uint32_t vertex_count_ = 0;
  bool want_normals_ = false;
  std::vector<float> positions_;
  std::vector<float> normals_;
  bool done_ = false;
  Status status_;
  FrameTiming timing_;
  uint32_t next_vertex_ = 0;
  bool finished_ = false;
  int64_t encode_ns_ = 0;
  FrameRecord record_;  // for the metrics
};

}  // namespace skinserve::server
