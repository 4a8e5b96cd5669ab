// FrameSocketClient: a connection to a server's frame socket (skinserve --frame-socket PATH;
// docs/serving/frame-socket.md), for clients on the server's host: StreamSkin's requests
// and answers without gRPC (skinserve/wire/frame_socket_protocol.h). The answers are the
// same SkinResponse parts StreamSkin sends, to be read with RawPart / FrameAssembler /
// TickAssembler; frames into a shared-memory region name regions this process registered
// over gRPC (on a unix: address), as on StreamSkin. One thread may Write while another
// Reads; each of the two is for one thread at a time.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include <atomic>
#include <memory>
#include <string>

#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::client {

class FrameSocketClient {
 public:
  // Connects to the socket at `path` and sends the protocol's greeting. UNAVAILABLE naming
  // the path when nothing listens there. A server that refuses the connection says why in
  // its last message: the first Read returns false and Finish has it.
  static Result<std::unique_ptr<FrameSocketClient>> Connect(const std::string& path);
  ~FrameSocketClient();
  FrameSocketClient(const FrameSocketClient&) = delete;
  FrameSocketClient& operator=(const FrameSocketClient&) = delete;

  // Sends one request (a frame or a tick). False once the connection is gone (Finish says
  // why); the request then was not delivered.
  bool Write(const v1::SkinRequest& request);
  // The next answer part, as the server serialized it. False at the connection's end: read
  // Finish then.
  bool Read(grpc::ByteBuffer* part);
  // No more requests: the server answers those sent, then ends the connection OK.
  void WritesDone();
  // After Read returned false: why the connection ended, as the server's last message says
  // (OK: WritesDone, and every request was answered), or what broke the socket.
  Status Finish() const { return end_; }
  // From any thread: ends the connection now (a Read waiting returns false, Finish says
  // CANCELLED).
  void Cancel();

 private:
  explicit FrameSocketClient(int fd) : fd_(fd) {}
  bool ReadExactly(void* into, std::size_t bytes);

  const int fd_;
  std::string out_;  // the request being sent: header and message, reused
  Status end_ = Unavailable("the frame socket closed without saying why");
  std::atomic<bool> cancelled_{false};
};

}  // namespace skinserve::client
