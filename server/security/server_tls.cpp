#include "security/server_tls.h"

#include <fmt/format.h>
#include <grpcpp/security/tls_certificate_provider.h>
#include <grpcpp/security/tls_credentials_options.h>

#include <fstream>
#include <sstream>

namespace skinserve::server {
namespace {

// The file at `path` must be readable and hold a PEM block ("-----BEGIN "): the provider
// itself would only log its failure and fail every handshake.
Status CheckPemFile(const char* flag, const std::string& path) {
  std::ifstream in(path);
  if (!in) return InvalidArgument(fmt::format("{} '{}': cannot read the file", flag, path));
  std::stringstream text;
  text << in.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos) {
    return InvalidArgument(
        fmt::format("{} '{}': no PEM block (-----BEGIN ...) in the file", flag, path));
  }
  return Status::Ok();
}

}  // namespace

Result<std::shared_ptr<grpc::ServerCredentials>> MakeTcpCredentials(const ServerOptions& options) {
  if (Status s = options.CheckSecurity(); !s.ok()) return s;
  if (options.tls_cert.empty()) return grpc::InsecureServerCredentials();
  for (const auto& [flag, path] :
       {std::pair{"--tls-cert", &options.tls_cert}, std::pair{"--tls-key", &options.tls_key},
        std::pair{"--tls-client-ca", &options.tls_client_ca}}) {
    if (path->empty()) continue;
    if (Status s = CheckPemFile(flag, *path); !s.ok()) return s;
  }
  const auto refresh = static_cast<unsigned>(options.tls_refresh_seconds);
  const bool mutual = !options.tls_client_ca.empty();
  auto provider = mutual ? std::make_shared<grpc::experimental::FileWatcherCertificateProvider>(
                               options.tls_key, options.tls_cert, options.tls_client_ca, refresh)
                         : std::make_shared<grpc::experimental::FileWatcherCertificateProvider>(
                               options.tls_key, options.tls_cert, refresh);
  grpc::experimental::TlsServerCredentialsOptions tls(provider);
  tls.watch_identity_key_cert_pairs();
  if (mutual) {
    tls.watch_root_certs();
    tls.set_cert_request_type(GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  } else {
    tls.set_cert_request_type(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  }
  return grpc::experimental::TlsServerCredentials(tls);
}

}  // namespace skinserve::server
