// UnitStream: what an open-loop stream (load_runner.cpp) sends its units on and reads their
// answers from: a StreamSkin call, or a connection to the server's frame socket
// (RunConfig::frame_socket, the `socket` data plane). Both carry the same requests and the
// same answer parts.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include <chrono>
#include <memory>
#include <string>

#include "skinserve/client/skin_client.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::load {

class UnitStream {
 public:
  virtual ~UnitStream() = default;
  virtual bool Write(const v1::SkinRequest& request) = 0;
  virtual bool Read(grpc::ByteBuffer* part) = 0;
  virtual void WritesDone() = 0;
  // After Read returned false: the stream's end status.
  virtual Status Finish() = 0;
  // From any thread: ends the stream (its reads), as an idle watchdog does.
  virtual void Cancel() = 0;
};

// A StreamSkin call of `client`.
std::unique_ptr<UnitStream> OpenGrpcStream(client::SkinClient& client);
// A connection to the frame socket at `path`; a stream that fails at once (Finish: why)
// when it cannot connect.
std::unique_ptr<UnitStream> OpenFrameSocketStream(const std::string& path);

}  // namespace skinserve::load
