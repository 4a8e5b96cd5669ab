// StreamAnswer: what a reactor's in-flight slot holds, a frame (FrameJob) or a tick
// (TickJob): something that is answered in parts, written one at a time in request order.
// The reactors drive it under their own lock; the job may be finished on a compute thread.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include "skinserve/model/status.h"

namespace skinserve::server {

class StreamAnswer {
 public:
  StreamAnswer() = default;
  StreamAnswer(const StreamAnswer&) = delete;
  StreamAnswer& operator=(const StreamAnswer&) = delete;

  virtual bool done() const = 0;  // under the listener's lock
  virtual void set_done() = 0;
  // The answer's own status: not OK when it failed whole (on Skin, the RPC's status).
  virtual const Status& status() const = 0;
  // Whether a part is ready to go out that was not handed out yet.
  virtual bool HasPartToSend() = 0;
  // The next response part, serialized; nullptr while none is ready. `*last` tells
  // whether it is the answer's final part. Valid until PartWritten or the next call.
  virtual const grpc::ByteBuffer* NextPart(bool* last) = 0;
  // The part handed out last was written (or failed): the job lets go of it.
  virtual void PartWritten() = 0;
  // Lets go of every slice the job itself still holds (an answer abandoned mid-way).
  virtual void DropWire() = 0;
  // Whether gRPC still holds slices of the job's buffers: until then it is not reused.
  virtual bool wire_in_use() const = 0;
  virtual bool is_tick() const { return false; }

 protected:
  ~StreamAnswer() = default;
};

}  // namespace skinserve::server
