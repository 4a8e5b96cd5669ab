// Ticks (SkinRequest.characters, issue 41): many characters skinned by one request. A
// game server drives dozens to thousands of characters each tick; sent as one request they
// share its cost, are spread over the server's compute threads together and answered once
// (docs/serving/ticks.md). A character's bad input fails that character alone.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/client/skin_client.h"

namespace skinserve::client {

// One character of a tick: its mesh, its palette (or a crowd's palettes back to back:
// options.instances) and what it asks of the server, as a frame's SkinOptions do.
// options.early_parts must stay false (a tick's characters come as they finish anyway; set,
// the server fails the character). With options.output the server writes the character
// into its range of the region (RegionOutput::offset) and answers only its RegionWrite.
struct TickCharacter {
  std::string mesh_id;
  std::span<const float> palette;  // caller-owned: read when the tick is sent
  SkinOptions options;
};

// Builds a tick: characters in order (a character's index is its place in the answer).
// Meant to be reused from tick to tick: Clear keeps the storage, so a steady tick of the
// same characters allocates nothing here.
class Tick {
 public:
  // Adds a character and returns its index. `palette` and the options' spans (morph
  // weights) are the caller's and must stay valid until the tick is sent.
  std::size_t Add(const std::string& mesh_id, std::span<const float> palette,
                  const SkinOptions& options = {});
  // A character whose palette the server computes from `pose` (SkinRequest.pose; its clip
  // ids and layers are the caller's, read when the tick is sent).
  std::size_t AddPose(const std::string& mesh_id, const Pose& pose, SkinOptions options = {});
  void Clear() { size_ = 0; }  // keeps frame()
  // The tick's number (SkinRequest.frame), echoed in its answer.
  void set_frame(uint64_t frame) { frame_ = frame; }
  uint64_t frame() const { return frame_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const TickCharacter& character(std::size_t i) const { return characters_[i]; }
  std::span<const TickCharacter> characters() const { return {characters_.data(), size_}; }

  // Writes the tick into `request` (reusing its messages' storage). `slot_offset` is added
  // to every region character's offset (StreamTicks' slots).
  void ToWire(v1::SkinRequest* request, uint64_t slot_offset = 0) const;

 private:
  std::vector<TickCharacter> characters_;  // [0, size_) in use; the rest kept for reuse
  std::size_t size_ = 0;
  uint64_t frame_ = 0;
};

// A tick's answer: one FrameResult per character, in the request's order. A character
// that failed has its own status (the server's message names the character and the field)
// and empty arrays; the others hold their vertices, or, written into a region, view it
// (FrameResult::in_region). Reusable from tick to tick like FrameResult.
struct TickResult {
  uint64_t frame = 0;
  // The tick's own outcome: not OK when the tick failed whole (refused, the stream broke);
  // then every character carries the same status.
  Status status;
  std::vector<FrameResult> characters;

  // Characters whose status is not OK.
  std::size_t failed() const;
};

// Gathers a tick's parts (every character's vertex parts, characters in any order, then
// the final part with SkinResponse.tick) into a TickResult; true once the final part has
// arrived. `tick` is the request's tick (it must outlive the assembler: its characters'
// region outputs are read). A part against the contract fails the tick (INTERNAL); a tick
// the server refused whole fails with the server's status. One per tick; the result may be
// reused from tick to tick.
class TickAssembler {
 public:
  TickAssembler(const Tick& tick, TickResult* result);
  bool Add(const grpc::ByteBuffer& part, RawPart* reader);

 private:
  bool Finish(const v1::SkinResponse& final_part);
  // The tick failed whole: every character takes `status`.
  void FailTick(Status status);

  const Tick& tick_;
  TickResult* result_;
  std::vector<FrameAssembler> assemblers_;  // one per character
  std::vector<uint8_t> complete_;           // per character: its vertex parts ended
  bool failed_ = false;
};

// StreamTicks: tick after tick over StreamSkin, a window of ticks in flight. Every tick
// sent is handed to the sink exactly once. A character answered NOT_FOUND makes the client
// upload its mesh again (if it uploaded it: SkinClient::Upload or Remember) and send the
// tick again; UNAVAILABLE reconnects, as StreamFrames does.
struct TickStreamOptions {
  uint64_t first_tick = 0;  // the first tick's frame number
  uint64_t ticks = 100;
  int window = 2;  // ticks in flight (the server's stream window counts a tick as one frame)
  // Region characters: tick i in flight writes each character at its output.offset + slot *
  // region_stride (slot < window); 0 with a window above 1 is refused when a character has
  // a region output.
  uint64_t region_stride = 0;
  int max_reconnects = 3;
  int max_reuploads = 8;
  const std::atomic<bool>* stop = nullptr;  // as StreamOptions::stop
};

// Fills tick `frame` into `tick` (cleared, with set_frame(frame) done, before the call; its
// spans must stay valid until the next call). A tick sent again (after a re-upload) is asked for
// again, so the source must give the same tick for the same frame.
using TickSource = std::function<void(uint64_t frame, Tick* tick)>;
// Called once per tick sent, in order of answers; latency is from send to the final part.
// `result` is reused: valid only during the call.
using TickSink = std::function<void(TickResult& result, std::chrono::nanoseconds latency)>;

struct TickStreamSummary {
  uint64_t sent = 0;                 // ticks written to a stream (resends not counted twice)
  uint64_t answered = 0;             // ticks answered (some characters may have failed)
  uint64_t failed = 0;               // ticks failed whole (TickResult::status)
  uint64_t characters_answered = 0;  // characters answered without error
  uint64_t characters_failed = 0;    // characters with an error, in answered or failed ticks
  uint64_t reconnects = 0;
  uint64_t reuploads = 0;
};

Status StreamTicks(SkinClient& client, const TickStreamOptions& options, const TickSource& source,
                   const TickSink& sink, TickStreamSummary* summary = nullptr);

}  // namespace skinserve::client
