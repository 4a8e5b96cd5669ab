#include "skinserve/client/channel.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::client {
namespace {
constexpr int kStreamWindowBytes = 4 << 20;

Result<std::string> ReadPem(const char* option, const std::string& path) {
  std::ifstream in(path);
  if (!in) return InvalidArgument(fmt::format("{} '{}': cannot read the file", option, path));
  std::stringstream text;
  text << in.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos) {
    return InvalidArgument(
        fmt::format("{} '{}': no PEM block (-----BEGIN ...) in the file", option, path));
  }
  return text.str();
}

int Milliseconds(std::chrono::milliseconds d) {
  return static_cast<int>(std::clamp<int64_t>(d.count(), 0, INT32_MAX));
}

}  // namespace

Result<ChannelOptions> ChannelOptionsFromFiles(const TlsFiles& files) {
  ChannelOptions options;
  if (!files.enabled()) return options;
  if (files.ca.empty()) {
    return InvalidArgument(
        "--tls-cert/--tls-key without --tls-ca: name the CA that signed the server's certificate");
  }
  if (files.cert.empty() != files.key.empty()) {
    return InvalidArgument(
        fmt::format("--tls-cert and --tls-key go together: --tls-cert is '{}', --tls-key '{}'",
                    files.cert, files.key));
  }
  grpc::SslCredentialsOptions ssl;
  auto ca = ReadPem("--tls-ca", files.ca);
  if (!ca.ok()) return ca.status();
  ssl.pem_root_certs = *ca;
  if (!files.cert.empty()) {
    auto cert = ReadPem("--tls-cert", files.cert);
    if (!cert.ok()) return cert.status();
    auto key = ReadPem("--tls-key", files.key);
    if (!key.ok()) return key.status();
    ssl.pem_cert_chain = *cert;
    ssl.pem_private_key = *key;
  }
  options.credentials = grpc::SslCredentials(ssl);
  options.server_name = files.server_name;
  return options;
}

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, int connection) {
  return MakeChannel(target, ChannelOptions{}, connection);
}

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, const ChannelOptions& options,
                                           int connection) {
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
  if (options.keepalive_time.count() > 0) {
    args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, Milliseconds(options.keepalive_time));
    args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, Milliseconds(options.keepalive_timeout));
    // Keepalive pings also while this side sends nothing (a stream waiting for answers):
    // gRPC otherwise stops pinging after two pings without data, and a blackholed
    // server would never be noticed. No pings on a channel without calls.
    args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
    args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 0);
  }
  if (!options.server_name.empty()) {
    args.SetSslTargetNameOverride(options.server_name);
  }
  return grpc::CreateCustomChannel(
      target, options.credentials ? options.credentials : grpc::InsecureChannelCredentials(), args);
}

std::string ConnectionHint(const Status& status) {
  if (status.code() != StatusCode::kUnavailable) return "";
  const std::string& m = status.message();
  if (m.find("Socket closed") != std::string::npos) {
    return "the server closed the connection at once: a TLS server refuses plaintext clients "
           "(give --tls-ca), a mutual-TLS server refuses clients without a certificate (give "
           "--tls-cert and --tls-key)";
  }
  if (m.find("wrong version number") != std::string::npos) {
    return "the server does not speak TLS there (plaintext, or a unix: address): leave out "
           "--tls-ca, --tls-cert and --tls-key";
  }
  if (m.find("certificate verify failed") != std::string::npos) {
    return "the server's certificate is not signed by the CA of --tls-ca";
  }
  return "";
}

Status CheckHealth(grpc::Channel& channel, std::chrono::milliseconds timeout,
                   const std::string& service) {
  auto stub = grpc::health::v1::Health::NewStub(
      std::shared_ptr<grpc::Channel>(&channel, [](grpc::Channel*) {}));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
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
