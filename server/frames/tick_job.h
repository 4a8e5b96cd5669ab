// TickJob: one tick (SkinRequest.characters) on its way through the server. Each character
// is a FrameJob in tick mode, prepared and submitted like a frame; all of them go to the
// engine at once, so its compute threads spread them. A character that fails (its input,
// its limits, a full queue) fails alone, its error named in the final part. The answer:
// each character's vertex parts as it finishes (characters in finish order), then one
// final part (`last`, `tick`: a header per character in request order). The job and its
// character jobs are kept by their stream (TickJobs) and reused tick after tick, so the
// steady state allocates nothing of its own. Characters written into a GPU region hold it
// until the tick is complete, when each region is signalled once (SignalGpuRegions).
#pragma once

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/slice.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "frames/frame_job.h"
#include "frames/inflight_budget.h"
#include "frames/stream_plan.h"
#include "rpc/stream_answer.h"
#include "shm/region_registry.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

class TickJob final : public StreamAnswer, private FrameJob::Listener {
 public:
  // `listener` hears of the tick as a whole (OnFrameDone once, OnPartsReady as characters
  // finish) and holds for the wire buffers of every character.
  TickJob(FrameJob::Listener* listener, InflightBudget* budget)
      : listener_(listener), budget_(budget) {}
  ~TickJob();

  // Prepares every character of the tick `request` and submits those prepared to the
  // engine. True: characters are in the engine and OnFrameDone will come. False: the tick
  // is answered already (it failed whole, or every character failed before the engine)
  // and no call will come.
  bool Start(v1::SkinRequest& request, Engine& engine, const std::string& default_backend,
             const RegionCaller& regions);

  bool done() const override { return done_; }
  void set_done() override { done_ = true; }
  const Status& status() const override { return status_; }
  bool HasPartToSend() override;
  const grpc::ByteBuffer* NextPart(bool* last) override;
  void PartWritten() override;
  void DropWire() override;
  bool wire_in_use() const override;
  bool is_tick() const override { return true; }

 private:
  void OnFrameDone(StreamAnswer* character) override;
  void OnPartsReady(StreamAnswer*) override {}  // characters never send early parts
  void HoldForWire() override { listener_->HoldForWire(); }
  void ReleaseForWire() override { listener_->ReleaseForWire(); }

  // The tick fails whole with `status` (its answer one error part).
  void FailTick(Status status);
  // Prepares character i; false: it failed alone (answered with its error).
  bool PrepareCharacter(uint32_t i, v1::SkinRequest& character, Engine& engine,
                        const std::string& default_backend, const RegionCaller& regions);
  // Character `i` failed in Start (the listener's lock is held: it is not told): it joins
  // the finish order. Never the tick's last, since Start holds one.
  void CharacterDone(uint32_t i);
  // Once every character is done: each GPU region its characters went into signalled once
  // (its semaphore, GpuRegion::FrameWritten), a region that fails failing its characters.
  void SignalGpuRegions();
  // Once every character is done: SignalGpuRegions, then the final part, over final_bytes_.
  void BuildFinalPart();
  // Moves next_sending_ past characters that have no part to send (failed, in a region).
  // Under mutex_.
  FrameJob* SendingLocked();
  static void FinalReleased(void* job);

  FrameJob::Listener* const listener_;
  InflightBudget* const budget_;
  // SignalGpuRegions' regions of this tick and how their signal went (empty between).
  std::vector<std::pair<std::shared_ptr<GpuRegion>, Status>> signalled_;
  std::vector<std::unique_ptr<FrameJob>> characters_;  // [0, count_) in use; kept for reuse
  // Character i's plan (and its hold on the region it writes into), kept from tick to tick
  // and reused while that character's settings stay.
  std::vector<std::unique_ptr<StreamPlan>> character_plans_;
  SkinGroup group_;                  // the characters submitted, one queue place together
  std::vector<uint32_t> submitted_;  // group_.jobs[k] is character submitted_[k]
  std::vector<Status> verdicts_;     // the engine's verdict on group_.jobs[k]
  uint32_t count_ = 0;
  uint64_t frame_ = 0;
  Status status_;
  bool done_ = false;
  // Characters not done yet, plus one held by Start until every character is submitted.
  std::atomic<uint32_t> pending_{0};

  std::mutex mutex_;             // the finish order, against the compute threads
  std::vector<uint32_t> order_;  // characters in finish order: [0, finished_)
  uint32_t finished_ = 0;
  uint32_t next_sending_ = 0;    // index into order_ of the character sending its parts
  FrameJob* writing_ = nullptr;  // the character whose part is being written, if any
  bool final_ready_ = false;
  bool final_handed_out_ = false;

  v1::SkinResponse final_;          // reused: the final part, its headers kept
  std::string final_bytes_;         // its serialization, which gRPC reads in place
  std::atomic<int> final_refs_{0};  // 1 while gRPC holds final_bytes_
  std::optional<grpc::ByteBuffer> final_out_;
  bool error_part_ = false;  // the tick failed whole: error_bytes_ is its answer
  grpc::ByteBuffer error_bytes_;
};

// A stream's tick jobs, reused tick after tick (the job freed last first).
class TickJobs {
 public:
  TickJobs(FrameJob::Listener* listener, InflightBudget* budget)
      : listener_(listener), budget_(budget) {}
  // A job whose answer gRPC has let go of, or a new one.
  TickJob& Take();
  // `answer` is free again; false if it is no tick (the caller's own job).
  bool Recycle(StreamAnswer* answer);
  void DropWire();

 private:
  FrameJob::Listener* const listener_;
  InflightBudget* const budget_;
  std::vector<std::unique_ptr<TickJob>> jobs_;
  std::vector<TickJob*> idle_;
};

}  // namespace skinserve::server
