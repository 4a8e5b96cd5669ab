// Skin: one frame. The request goes to the engine's queue; the engine's completion starts
// the writes, one bounded part at a time. Nothing runs on gRPC's threads but the copies.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <memory>
#include <mutex>

#include "frames/frame_job.h"
#include "frames/skin_request_reader.h"
#include "frames/tick_job.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

// Raw messages: the request is parsed here, the answer goes out as the job's parts.
class SkinReactor final : public grpc::ServerWriteReactor<grpc::ByteBuffer>,
                          private FrameJob::Listener {
 public:
  SkinReactor(Engine* engine,  // null: warming up
              const std::string& default_backend, const grpc::ByteBuffer& request,
              InflightBudget* budget, RegionCaller regions, const SkinRequestLimits& limits = {});
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 private:
  void OnFrameDone(StreamAnswer* job) override;
  void OnPartsReady(StreamAnswer* job) override;
  void HoldForWire() override { refs_.fetch_add(1); }
  void ReleaseForWire() override { Unref(); }
  // The request is a tick: its TickJob answers the call.
  void StartTick(v1::SkinRequest& request, Engine& engine, const std::string& default_backend,
                 const RegionCaller& regions, InflightBudget* budget);
  void WriteNextLocked();
  void FinishLocked(const grpc::Status& status);
  void Unref();

  std::mutex mutex_;
  FrameJob job_;
  std::unique_ptr<TickJob> tick_;  // when the request is a tick
  StreamAnswer* answer_ = &job_;   // the frame's job, or the tick's
  bool finished_ = false;
  bool writing_ = false;
  // gRPC's reference (dropped in OnDone), the engine's (dropped after its callback) and
  // the answer's (while gRPC holds the job's wire buffer): the reactor lives until all
  // are gone.
  std::atomic<int> refs_{1};
};

}  // namespace skinserve::server
