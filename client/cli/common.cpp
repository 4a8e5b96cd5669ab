#include <fmt/format.h>

#include <map>

#include "commands.h"

namespace skinserve::cli {
namespace {

std::chrono::milliseconds Milliseconds(double seconds) {
  return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

}  // namespace

Result<std::shared_ptr<grpc::Channel>> CommonOptions::Channel() const {
  auto options = client::ChannelOptionsFromFiles(tls);
  if (!options.ok()) return options.status();
  options->keepalive_time = Milliseconds(keepalive_seconds);
  options->keepalive_timeout = Milliseconds(keepalive_timeout_seconds);
  return client::MakeChannel(target, *options);
}

client::CallLimits CommonOptions::Limits() const {
  return {.deadline = Milliseconds(deadline_seconds),
          .upload_deadline = Milliseconds(upload_deadline_seconds),
          .stream_idle = Milliseconds(stream_idle_seconds)};
}

void AddCommonOptions(CLI::App& app, CommonOptions& common) {
  app.add_option("--target", common.target,
                 "gRPC target of the server(s), e.g. 127.0.0.1:50051, "
                 "ipv4:127.0.0.1:50051,127.0.0.1:50052 (round_robin) or unix:PATH")
      ->envname("SKINSERVE_TARGET")
      ->capture_default_str();
  app.add_option("--tls-ca", common.tls.ca,
                 "TLS: PEM CA certificate(s) that signed the server's certificate (without it: "
                 "plaintext; unix: addresses are always plaintext)")
      ->envname("SKINSERVE_CLIENT_TLS_CA");
  app.add_option("--tls-cert", common.tls.cert,
                 "mutual TLS: this client's PEM certificate chain (with --tls-key)")
      ->envname("SKINSERVE_CLIENT_TLS_CERT");
  app.add_option("--tls-key", common.tls.key, "mutual TLS: this client's PEM private key")
      ->envname("SKINSERVE_CLIENT_TLS_KEY");
  app.add_option("--tls-server-name", common.tls.server_name,
                 "TLS: the name the server's certificate must carry, when the target's host is "
                 "not it (e.g. an IP address)")
      ->envname("SKINSERVE_CLIENT_TLS_SERVER_NAME");
  app.add_option("--deadline-seconds", common.deadline_seconds,
                 "deadline of each call and each single frame (0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--upload-deadline-seconds", common.upload_deadline_seconds,
                 "deadline of each mesh upload, whole (0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--stream-idle-seconds", common.stream_idle_seconds,
                 "a stream with frames in flight and no answer for this long is ended "
                 "(DEADLINE_EXCEEDED) and the next one opened (0: wait for ever)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--keepalive-seconds", common.keepalive_seconds,
                 "with calls open, ping the server this often (0: never); a ping unanswered "
                 "for --keepalive-timeout-seconds closes the connection (UNAVAILABLE)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--keepalive-timeout-seconds", common.keepalive_timeout_seconds,
                 "how long a keepalive ping may go unanswered")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

void MeshOptionsCli::Add(CLI::App* command) {
  command->add_option("--vertices", spec.vertex_count, "synthetic mesh: vertex count")
      ->capture_default_str();
  command->add_option("--bones", spec.influences, "synthetic mesh: influences per vertex (1..8)")
      ->capture_default_str();
  command->add_option("--joints", spec.joint_count, "synthetic mesh: joint count")
      ->capture_default_str();
  command->add_flag("--normals", spec.normals, "synthetic mesh: with normals");
  command->add_option("--seed", spec.seed, "synthetic mesh: seed")->capture_default_str();
}

void AddMethodOption(CLI::App* command, SkinningMethod* method) {
  command
      ->add_option("--method", *method,
                   "skinning method: linear (default), or dual-quaternion (rigid joints only)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, SkinningMethod>{
              {"linear", SkinningMethod::kLinear},
              {"dual-quaternion", SkinningMethod::kDualQuaternion}},
          CLI::ignore_case));
}

int Report(const Status& status) {
  if (status.ok()) return 0;
  fmt::print(stderr, "error: {}\n", status.ToString());
  if (const std::string hint = client::ConnectionHint(status); !hint.empty()) {
    fmt::print(stderr, "hint: {}\n", hint);
  }
  return 1;
}

}  // namespace skinserve::cli
