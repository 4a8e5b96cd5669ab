// StreamFrames: frame after frame over StreamSkin with a bounded window in flight. Every
// frame sent is handed to the sink exactly once, answered or failed: none is lost
// silently. A frame answered NOT_FOUND makes the client upload its mesh again and resend
// it; a stream broken by UNAVAILABLE (a replica gone) fails its in-flight frames and
// continues on a new stream, which the channel's round_robin places on a live replica.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "skinserve/client/pose.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::client {

struct StreamOptions {
  std::string mesh_id;
  std::string backend;  // empty: the server's default
  bool want_normals = false;
  bool want_tangents = false;  // needs want_normals (SkinOptions::want_tangents)
  SkinningMethod method = SkinningMethod::kLinear;
  VertexEncoding encoding = VertexEncoding::kFloat32;  // decoded to float32 for the sink
  // Crowd batches: each frame's palette holds this many instances' palettes back to back,
  // and its result this many vertex sets.
  uint32_t instances = 1;
  // Same host: every frame is written into this region, each frame in flight into its own
  // slot (RegionOutput::stride); the sink's result views it (FrameResult::in_region).
  RegionOutput output;
  bool early_parts = false;  // as SkinOptions::early_parts
  uint64_t first_frame = 0;
  uint64_t frames = 100;
  int window = 4;  // frames in flight
  // New streams after UNAVAILABLE, in a row without an answer between them: a long stream
  // that servers end now and then (maximum connection age) goes on for ever. The frames in
  // flight on a stream that broke after answering are reported failed; on one that broke
  // before its first answer (it never got going) they are sent again on the next stream.
  int max_reconnects = 3;
  // Uploads after NOT_FOUND. Behind round_robin an upload may land on another replica
  // than the stream's, so allow a few.
  int max_reuploads = 8;
  // When set and true, no new frame is sent (those in flight are still answered): for
  // runs bounded by time rather than by `frames`.
  const std::atomic<bool>* stop = nullptr;
  // Frame f's morph target weights (sparse; valid until the next call), sent with its
  // palette; empty function: no weights. A crowd's instances share them.
  std::function<std::span<const MorphWeight>(uint64_t frame)> morph_weights;
  // Crowds: frame f's weights per instance, one entry per instance (valid until the next
  // call), instead of morph_weights; empty function: none.
  std::function<std::span<const std::vector<MorphWeight>>(uint64_t frame)> instance_morph_weights;
  // Frame f's pose (docs/serving/animation.md#pose; its skeleton id and layers valid until
  // the next call): a pose that is not empty goes instead of a palette, and the palette
  // source is not asked for that frame; an empty pose, or an empty function, sends the
  // palette. A pose is one character's: instances must be 1.
  std::function<Pose(uint64_t frame)> pose;
};

// Gives frame f's palette (12 * joints * instances floats). Best without waste: a callable
// returning a std::span<const float> or a const reference to storage that stays valid until
// the next call; the palette is copied straight into the reused request. A callable
// returning a std::vector<float> by value also works (the vector is kept until the next
// call), at the price of its allocation per frame.
class PaletteSource {
 public:
  template <typename F>
  requires std::is_invocable_v<F&, uint64_t> PaletteSource(
      F source) {  // NOLINT: implicit, so that callers pass lambdas
    using Returned = std::invoke_result_t<F&, uint64_t>;
    if constexpr (std::is_lvalue_reference_v<Returned> ||
                  std::is_same_v<std::remove_cvref_t<Returned>, std::span<const float>> ||
                  std::is_same_v<std::remove_cvref_t<Returned>, std::span<float>>) {
      source_ = [source = std::move(source)](uint64_t frame) mutable {
        return std::span<const float>(source(frame));
      };
    } else {
      source_ = [source = std::move(source), held = std::vector<float>()](uint64_t frame) mutable {
        held = source(frame);
        return std::span<const float>(held);
      };
    }
  }
  // Valid until the next call.
  std::span<const float> operator()(uint64_t frame) const { return source_(frame); }

 private:
  std::function<std::span<const float>(uint64_t)> source_;
};

// Called once per frame sent, in order of answers; latency is from send to last part.
// `result` is the stream's one reused FrameResult: valid only during the call (copy what
// must outlive it, or move its vectors out, which costs the next frame an allocation).
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
