// StreamFrames: frame after frame over StreamSkin with a bounded window in flight. Every
// frame sent is handed to the sink exactly once, answered or failed: none is lost
// silently. A frame answered NOT_FOUND makes the client upload its mesh again and resend
// it; a stream broken by UNAVAILABLE (a replica gone) fails its in-flight frames and
// continues on a new stream, which the channel's round_robin places on a live replica.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "skinserve/client/skin_client.h"

namespace skinserve::client {

struct StreamOptions {
  std::string mesh_id;
  std::string backend;  // empty: the server's default
  bool want_normals = false;
  SkinningMethod method = SkinningMethod::kLinear;
  uint64_t first_frame = 0;
  uint64_t frames = 100;
  int window = 4;          // frames in flight
  int max_reconnects = 3;  // new streams after UNAVAILABLE
  // Uploads after NOT_FOUND. Behind round_robin an upload may land on another replica
  // than the stream's, so allow a few.
  int max_reuploads = 8;
  // When set and true, no new frame is sent (those in flight are still answered): for
  // runs bounded by time rather than by `frames`.
  const std::atomic<bool>* stop = nullptr;
};

using PaletteSource = std::function<std::vector<float>(uint64_t frame)>;
// Called once per frame sent, in order of answers; latency is from send to last part.
using FrameSink = std::function<void(FrameResult& result, std::chrono::nanoseconds latency)>;

struct StreamSummary {
  uint64_t sent = 0;      // frames written to a stream (resends not counted twice)
  uint64_t answered = 0;  // frames whose result came back without error
  uint64_t failed = 0;    // frames reported to the sink with an error
  uint64_t reconnects = 0;
  uint64_t reuploads = 0;
};

// Returns the status of the last stream (OK when every frame was sent and its stream
// ended cleanly, even if single frames failed: see the sink and the summary).
Status StreamFrames(SkinClient& client, const StreamOptions& options, const PaletteSource& palette,
                    const FrameSink& sink, StreamSummary* summary = nullptr);

}  // namespace skinserve::client
