// Skin: one frame. The request goes to the engine's queue; the engine's completion starts
// the writes, one bounded part at a time. Nothing runs on gRPC's threads but the copies.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <mutex>

#include "frame_job.h"
#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class SkinReactor final : public grpc::ServerWriteReactor<v1::SkinResponse>,
                          private FrameJob::Listener {
 public:
  SkinReactor(Engine* engine,  // null: warming up
              const std::string& default_backend, const v1::SkinRequest& request,
              InflightBudget* budget);
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override { Unref(); }

 private:
  void OnFrameDone(FrameJob* job) override;
  void WriteNextLocked();
  void FinishLocked(const grpc::Status& status);
  void Unref();

  std::mutex mutex_;
  FrameJob job_;
  bool finished_ = false;
  // gRPC's reference (dropped in OnDone) and the engine's (dropped after its callback):
  // the reactor lives until both are gone.
  std::atomic<int> refs_{1};
};

}  // namespace skinserve::server
