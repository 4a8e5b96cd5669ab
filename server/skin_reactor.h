// Skin: one frame. The request goes to the engine's queue; the engine's completion starts
// the writes, one bounded part at a time. Nothing runs on gRPC's threads but the copies.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <mutex>

#include "frame_job.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

// Raw messages: the request is parsed here, the answer goes out as the job's parts.
class SkinReactor final : public grpc::ServerWriteReactor<grpc::ByteBuffer>,
                          private FrameJob::Listener {
 public:
  SkinReactor(Engine* engine,  // null: warming up
              const std::string& default_backend, const grpc::ByteBuffer& request,
              InflightBudget* budget, RegionCaller regions);
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 private:
  void OnFrameDone(FrameJob* job) override;
  void OnPartsReady(FrameJob* job) override;
  void HoldForWire() override { refs_.fetch_add(1); }
  void ReleaseForWire() override { Unref(); }
  void WriteNextLocked();
  void FinishLocked(const grpc::Status& status);
  void Unref();

  std::mutex mutex_;
  FrameJob job_;
  bool finished_ = false;
  bool writing_ = false;
  // gRPC's reference (dropped in OnDone), the engine's (dropped after its callback) and
  // the answer's (while gRPC holds the job's wire buffer): the reactor lives until all
  // are gone.
  std::atomic<int> refs_{1};
};

}  // namespace skinserve::server
