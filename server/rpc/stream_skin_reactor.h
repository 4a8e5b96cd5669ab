// StreamSkin: palettes in, vertices out, in request order. Each frame read goes to the
// engine's queue at once; at most `window` frames of a stream are in flight, beyond that
// the reactor stops reading (gRPC flow control pushes back on the client). Completed
// frames are written in order, one part at a time. A frame that fails is answered with
// its error and the stream carries on. Drained (server shutdown), the stream reads no
// more, answers the frames it has read and ends with UNAVAILABLE.
// Each stream keeps the FrameJobs it needed and reuses them, so after the first frames
// nothing is allocated per frame; their buffers count against the in-flight budget until
// the stream ends. A new frame takes the job freed last whose answer gRPC has let go of:
// a stream with one frame in flight (60 fps) reuses one job, whose buffers stay warm in
// cache, and grows (and page-faults in) only as many as it ever has in flight (at most
// `window`, and rarely one more whose answer is still on its way to the socket).
// A stream with no frame in flight is quiet; OpenStreams' watchdog ends one quiet too long
// (--stream-idle-seconds). All that costs a frame is one timestamp, stored when the last
// frame in flight is answered.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "frames/frame_job.h"
#include "frames/skin_request_reader.h"
#include "frames/stream_plan.h"
#include "frames/tick_job.h"
#include "rpc/open_streams.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

// Raw messages: requests are parsed here, answers go out as the jobs' serialized parts.
class StreamSkinReactor final : public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>,
                                private FrameJob::Listener {
 public:
  StreamSkinReactor(Engine* engine,  // null: warming up
                    std::string default_backend, int window, OpenStreams* open_streams,
                    InflightBudget* budget, RegionCaller regions,
                    const SkinRequestLimits& limits = {});
  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

  // Stops reading; the stream ends UNAVAILABLE once the frames read so far are answered.
  void Drain();
  // Keeps the reactor alive across a call from outside gRPC and the engine (OpenStreams).
  void Hold() { refs_.fetch_add(1); }
  void Release() { Unref(); }
  // Since when no frame has been in flight: the stream's start, or when its last frame in
  // flight was answered (meaningless while one is). Read by OpenStreams' watchdog.
  std::chrono::steady_clock::time_point quiet_since() const {
    return std::chrono::steady_clock::time_point(
        std::chrono::steady_clock::duration(quiet_since_.load()));
  }
  // Ends the stream UNAVAILABLE (`why`, then what was answered) if no frame is in flight
  // and none has been since `cutoff` or before; true if so.
  bool EndIfQuietSince(std::chrono::steady_clock::time_point cutoff, const std::string& why);

 private:
  void OnFrameDone(StreamAnswer* job) override;
  void OnPartsReady(StreamAnswer* job) override;
  void HoldForWire() override { refs_.fetch_add(1); }
  void ReleaseForWire() override { Unref(); }
  StreamAnswer& Slot(std::size_t i) { return *in_flight_jobs_[i % window_]; }
  // OnReadDone, under the lock: takes the request read into a job and prepares it; the job
  // to hand to the engine, or null (none, or answered already with its error).
  FrameJob* PrepareRead(bool ok);
  FrameJob* TakeIdleJobLocked();
  // The request read is a tick (tick_job.h): it takes the next slot, a window's one frame.
  void StartTickLocked();
  void PumpLocked();          // starts the next write, the next read or the finish, as due
  void RetireOldestLocked();  // the oldest answer is written and its job done: free its slot
  void FinishLocked(const grpc::Status& status);
  void Unref();

  Engine* engine_;
  const std::string default_backend_;
  const std::size_t window_;
  OpenStreams* open_streams_;
  InflightBudget* budget_;
  const RegionCaller regions_;  // the registry (null: shared memory is off) and the caller
  StreamPlan plan_;             // the stream's frame plan and its region handle (under mutex_)

  std::mutex mutex_;
  grpc::ByteBuffer request_bytes_;
  SkinRequestReader reader_;  // the parsed request, reused frame after frame
  uint64_t requests_read_ = 0;
  // Created as needed: at most window in flight, and rarely a few more whose answer
  // gRPC still holds (wire_in_use) when the next frame comes.
  std::vector<std::unique_ptr<FrameJob>> jobs_;
  // The frames in flight, oldest first: slots [oldest_, oldest_ + in_flight_) mod window.
  std::vector<StreamAnswer*> in_flight_jobs_;  // frames (FrameJob) or ticks (TickJob)
  std::vector<FrameJob*> idle_jobs_;           // a stack: the job freed last is reused first
  TickJobs ticks_;                             // the stream's tick jobs, likewise reused
  std::size_t oldest_ = 0;
  std::size_t in_flight_ = 0;
  bool writing_last_part_ = false;  // the write in progress ends the oldest frame
  // The oldest answer's last part is written but its job is not done yet: a compute thread
  // publishes a frame's parts before it leaves the job (OnFrameDone), so the slot is freed,
  // and the job reused, only then.
  bool oldest_written_ = false;
  std::optional<uint64_t> last_frame_read_;
  bool reading_ = false;
  bool reads_done_ = false;
  bool draining_ = false;
  bool writing_ = false;
  bool finished_ = false;
  std::atomic<std::chrono::steady_clock::rep> quiet_since_{
      std::chrono::steady_clock::now().time_since_epoch().count()};
  // gRPC's, plus one per frame the engine holds, per job whose wire buffer gRPC holds,
  // and per Hold.
  std::atomic<int> refs_{1};
};

}  // namespace skinserve::server
