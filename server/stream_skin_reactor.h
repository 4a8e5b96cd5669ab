// StreamSkin: palettes in, vertices out, in request order. Each frame read goes to the
// engine's queue at once; at most `window` frames of a stream are in flight, beyond that
// the reactor stops reading (gRPC flow control pushes back on the client). Completed
// frames are written in order, one part at a time. A frame that fails is answered with
// its error and the stream carries on. Drained (server shutdown), the stream reads no
// more, answers the frames it has read and ends with UNAVAILABLE.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "frame_job.h"
#include "open_streams.h"
#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class StreamSkinReactor final : public grpc::ServerBidiReactor<v1::SkinRequest, v1::SkinResponse> {
 public:
  StreamSkinReactor(Engine* engine,  // null: warming up
                    std::string default_backend, int window, OpenStreams* open_streams);
  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

  // Stops reading; the stream ends UNAVAILABLE once the frames read so far are answered.
  void Drain();
  // Keeps the reactor alive across a call from outside gRPC and the engine (OpenStreams).
  void Hold() { refs_.fetch_add(1); }
  void Release() { Unref(); }

 private:
  void OnFrameDone(const std::shared_ptr<FrameJob>& job, Status status, FrameTiming timing);
  void PumpLocked();  // starts the next write, the next read or the finish, as due
  void FinishLocked(const grpc::Status& status);
  void Unref();

  Engine* engine_;
  const std::string default_backend_;
  const std::size_t window_;
  OpenStreams* open_streams_;

  std::mutex mutex_;
  v1::SkinRequest request_;
  v1::SkinResponse part_;
  std::deque<std::shared_ptr<FrameJob>> frames_;  // in request order, oldest first
  std::optional<uint64_t> last_frame_read_;
  bool reading_ = false;
  bool reads_done_ = false;
  bool draining_ = false;
  bool writing_ = false;
  bool finished_ = false;
  std::atomic<int> refs_{1};  // gRPC's, plus one per frame the engine holds, plus holds
};

}  // namespace skinserve::server
