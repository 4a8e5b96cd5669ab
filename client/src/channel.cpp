#include "skinserve/client/channel.h"

#include <fmt/format.h>

#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::client {
namespace {
constexpr int kStreamWindowBytes = 4 << 20;
}  // namespace

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, int connection) {
  grpc::ChannelArguments args;
  // Subchannels (connections) are shared between channels whose arguments are equal.
  if (connection != 0) args.SetInt("skinserve.connection", connection);
  args.SetServiceConfigJSON(R"({"loadBalancingConfig": [{"round_robin": {}}]})");
  // Large frames arrive in parts of at most 1 MiB: the default limits are enough.
  // Flow control: a fixed 4 MiB receive window per stream instead of gRPC's BDP-probed one.
  // With BDP probing, the second 1 MiB part of a crowd frame stalled 10-15 ms now and then
  // on loopback (p99 of a 7-instance snorm16 frame 16.7 ms; 4.8-6.4 ms with these
  // settings; docs/serving/capacity.md). 4 MiB still fills a 50 ms round trip at 80 MB/s per
  // stream, which BDP probing would otherwise have grown the window to.
  args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, kStreamWindowBytes);
  return grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args);
}

Status CheckHealth(grpc::Channel& channel, std::chrono::milliseconds timeout) {
  auto stub = grpc::health::v1::Health::NewStub(
      std::shared_ptr<grpc::Channel>(&channel, [](grpc::Channel*) {}));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  grpc::Status status = stub->Check(&context, request, &response);
  if (!status.ok()) return wire::FromGrpc(status);
  if (response.status() != grpc::health::v1::HealthCheckResponse::SERVING) {
    return Unavailable(
        fmt::format("health: {}",
                    grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status())));
  }
  return Status::Ok();
}

Status WaitUntilServing(grpc::Channel& channel, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  Status last = Unavailable("not asked yet");
  while (std::chrono::steady_clock::now() < deadline) {
    last = CheckHealth(channel, std::chrono::milliseconds(1000));
    if (last.ok()) return last;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return Unavailable(fmt::format("not SERVING after {} ms: {}", timeout.count(), last.message()));
}

}  // namespace skinserve::client
