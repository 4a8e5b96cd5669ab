// StreamSkin: palettes in, vertices out, in request order. Each frame read goes to the
// engine's queue at once; at most `window` frames of a stream are in flight, beyond that
// the reactor stops reading (gRPC flow control pushes back on the client). Completed
// frames are written in order, one part at a time. A frame that fails is answered with
// its error and the stream carries on.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>

#include "frame_job.h"
#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class StreamSkinReactor final : public grpc::ServerBidiReactor<v1::SkinRequest, v1::SkinResponse> {
 public:
  StreamSkinReactor(Engine* engine,  // null: warming up
                    std::string default_backend, int window, std::atomic<uint64_t>* open_streams);
  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 private:
  void OnFrameDone(const std::shared_ptr<FrameJob>& job, Status status, FrameTiming timing);
  void PumpLocked();  // starts the next write, the next read or the finish, as due
  void Unref();

  Engine* engine_;
  const std::string default_backend_;
  const std::size_t window_;
  std::atomic<uint64_t>* open_streams_;

  std::mutex mutex_;
  v1::SkinRequest request_;
  v1::SkinResponse part_;
  std::deque<std::shared_ptr<FrameJob>> frames_;  // in request order, oldest first
  bool reading_ = false;
  bool reads_done_ = false;
  bool writing_ = false;
  bool finished_ = false;
  std::atomic<int> refs_{1};  // gRPC's, plus one per frame the engine holds
};

}  // namespace skinserve::server
