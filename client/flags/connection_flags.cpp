#include "connection_flags.h"

namespace skinserve::client {

std::chrono::milliseconds FlagMilliseconds(double seconds) {
  return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
}

Result<ChannelOptions> ConnectionFlags::ToChannelOptions() const {
  auto options = ChannelOptionsFromFiles(tls);
  if (!options.ok()) return options.status();
  options->keepalive_time = FlagMilliseconds(keepalive_seconds);
  options->keepalive_timeout = FlagMilliseconds(keepalive_timeout_seconds);
  return options;
}

void AddConnectionFlags(CLI::App& app, ConnectionFlags& flags) {
  app.add_option("--tls-ca", flags.tls.ca,
                 "TLS: PEM CA certificate(s) that signed the server's certificate (without it: "
                 "plaintext; unix: addresses are always plaintext)")
      ->envname("SKINSERVE_CLIENT_TLS_CA");
  app.add_option("--tls-cert", flags.tls.cert,
                 "mutual TLS: this client's PEM certificate chain (with --tls-key)")
      ->envname("SKINSERVE_CLIENT_TLS_CERT");
  app.add_option("--tls-key", flags.tls.key, "mutual TLS: this client's PEM private key")
      ->envname("SKINSERVE_CLIENT_TLS_KEY");
  app.add_option("--tls-server-name", flags.tls.server_name,
                 "TLS: the name the server's certificate must carry, when the target's host is "
                 "not it (e.g. an IP address)")
      ->envname("SKINSERVE_CLIENT_TLS_SERVER_NAME");
  app.add_option("--keepalive-seconds", flags.keepalive_seconds,
                 "with calls open, ping the server this often (0: never); a ping unanswered "
                 "for --keepalive-timeout-seconds closes the connection (UNAVAILABLE)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--keepalive-timeout-seconds", flags.keepalive_timeout_seconds,
                 "how long a keepalive ping may go unanswered")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

}  // namespace skinserve::client
