#include "unit_stream.h"

#include "skinserve/client/frame_socket_client.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::load {
namespace {

class GrpcStream final : public UnitStream {
 public:
  explicit GrpcStream(client::SkinClient& client) : stream_(client.StreamSkinRaw(&context_)) {}
  bool Write(const v1::SkinRequest& request) override { return stream_->Write(request); }
  bool Read(grpc::ByteBuffer* part) override { return stream_->Read(part); }
  void WritesDone() override { stream_->WritesDone(); }
  Status Finish() override { return wire::FromGrpc(stream_->Finish()); }
  void Cancel() override { context_.TryCancel(); }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<client::SkinClient::RawStream> stream_;
};

class SocketStream final : public UnitStream {
 public:
  explicit SocketStream(const std::string& path) {
    auto connected = client::FrameSocketClient::Connect(path);
    if (connected.ok()) {
      socket_ = std::move(connected).value();
    } else {
      failed_ = connected.status();
    }
  }
  bool Write(const v1::SkinRequest& request) override {
    return socket_ != nullptr && socket_->Write(request);
  }
  bool Read(grpc::ByteBuffer* part) override { return socket_ != nullptr && socket_->Read(part); }
  void WritesDone() override {
    if (socket_) socket_->WritesDone();
  }
  Status Finish() override { return socket_ ? socket_->Finish() : failed_; }
  void Cancel() override {
    if (socket_) socket_->Cancel();
  }

 private:
  std::unique_ptr<client::FrameSocketClient> socket_;
  Status failed_;
};

}  // namespace

std::unique_ptr<UnitStream> OpenGrpcStream(client::SkinClient& client) {
  return std::make_unique<GrpcStream>(client);
}

std::unique_ptr<UnitStream> OpenFrameSocketStream(const std::string& path) {
  return std::make_unique<SocketStream>(path);
}

}  // namespace skinserve::load
