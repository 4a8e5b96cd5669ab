// SkinRequestReader: turns the bytes of a SkinRequest off the wire into the message a frame
// is prepared from, without letting the bytes decide what the server holds. Protobuf
// allocates as it parses (a 4 MiB message of 2,000,000 empty instance_morph_weights
// entries parses into ~200 MB), so the reader first walks the bytes: every repeated field
// is counted against its limit before anything is copied, and an upper bound of the parsed
// size is charged to the in-flight budget before the parse. A request that holds more than
// kKeptRequestBytes is let go after its frame took what it needs, so a stream's reused
// message never keeps the capacity of its largest one.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include <cstdint>

#include "frames/inflight_budget.h"
#include "skinserve/engine/engine.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

// A stream keeps the storage of requests up to this size (a 64-instance crowd's palettes
// of 77 joints are 237 KB), so its steady state allocates nothing.
inline constexpr uint64_t kKeptRequestBytes = 1 << 20;

// The most bytes a request other than a tick may hold: gRPC's default message limit (the
// server accepts larger messages only for ticks, up to --max-tick-bytes).
inline constexpr uint64_t kMaxFrameRequestBytes = 4 << 20;

struct SkinRequestLimits {
  uint32_t max_instances = 64;  // instance_morph_weights entries (EngineOptions::max_instances)
  uint32_t max_morph_weights = 1024;  // targets or weights in one list (kMaxMorphTargets)
  // Ticks (SkinRequest.characters): characters in one request, nested ones included
  // (--max-tick-characters), and the request's bytes (--max-tick-bytes).
  uint32_t max_tick_characters = 256;
  uint64_t max_tick_bytes = 64ull << 20;
};

// `limits` with the engine's max_instances (the default while it is not there yet).
SkinRequestLimits WithMaxInstances(SkinRequestLimits limits, const Engine* engine);

// What the walk over the bytes found, before any parse.
struct SkinRequestScan {
  uint64_t frame = 0;         // SkinRequest.frame, so that a refusal can name the frame
  uint64_t parsed_bytes = 0;  // at most what the parsed message holds
  uint64_t characters = 0;    // a tick's characters (nested ones too); 0: a frame
  bool malformed = false;     // the bytes are no SkinRequest: nothing in them can be trusted
};

// Walks the bytes of a SkinRequest field by field without parsing it, a tick's characters
// too: INVALID_ARGUMENT naming the field and its limit when a repeated field is over it, or
// when the bytes are no SkinRequest at all; RESOURCE_EXHAUSTED naming the option when a
// tick is over --max-tick-characters or --max-tick-bytes (or a frame over
// kMaxFrameRequestBytes). Reads `bytes` without consuming it.
Status ScanSkinRequest(grpc::ByteBuffer* bytes, const SkinRequestLimits& limits,
                       SkinRequestScan* scan);

class SkinRequestReader {
 public:
  SkinRequestReader(InflightBudget* budget, const SkinRequestLimits& limits)
      : budget_(budget), limits_(limits) {}
  ~SkinRequestReader() { budget_->Release(charged_); }
  SkinRequestReader(const SkinRequestReader&) = delete;
  SkinRequestReader& operator=(const SkinRequestReader&) = delete;

  // Scans, charges and parses `bytes` (consumed) into request(). On error the frame
  // number the scan found, if any, is in scan().frame; RESOURCE_EXHAUSTED when the
  // budget cannot hold the parsed message.
  Status Read(grpc::ByteBuffer* bytes);
  const v1::SkinRequest& request() const { return request_; }
  // The frame's job takes the palette's bytes out of it (FrameJob::Prepare).
  v1::SkinRequest* mutable_request() { return &request_; }
  const SkinRequestScan& scan() const { return scan_; }
  // After the frame was prepared (it copies what it keeps): lets go of a large request's
  // storage and its charge.
  void Trim();
  uint64_t charged() const { return charged_; }

 private:
  InflightBudget* const budget_;
  const SkinRequestLimits limits_;
  v1::SkinRequest request_;
  SkinRequestScan scan_;
  uint64_t charged_ = 0;  // the largest parsed bound since the last trim
};

}  // namespace skinserve::server
