// What the security tests share: certificates made once per process with
// scripts/make-dev-certs.sh (two independent CAs, "a" and "b", each with a server and the
// clients operator, renderer and guest), servers in this process with given options, and
// channels that present a chosen client's certificate.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "rpc/skin_server.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {

// "DIR/a/server.pem" for Certificate("a", "server", "pem").
std::string Certificate(const std::string& ca, const std::string& name, const std::string& ext);

// A fresh folder under the test's temporary directory.
std::string TemporaryFolder(const std::string& name);

// Options that start quickly: two CPU backends (no OpenCL build), warnings only.
server::ServerOptions QuickServerOptions();
// The server's TLS files from CA `ca`; mutual TLS (its client CA) when `mutual`.
void UseServerTls(server::ServerOptions* options, const std::string& ca, bool mutual);

// Starts `options` on 127.0.0.1:0 besides any address it lists; fails the test if it
// cannot.
std::unique_ptr<server::SkinServer> StartServer(server::ServerOptions options);

// Trusts CA `trusted_ca`'s server certificates; presents `client` of CA `client_ca` (none
// when `client` is empty).
client::ChannelOptions ClientTls(const std::string& trusted_ca, const std::string& client = "",
                                 const std::string& client_ca = "");

// Upload a small mesh, skin a frame and stream a few, each answer checked against the
// float64 reference; OK or the first error.
Status UploadSkinAndStream(client::SkinClient& client);

// Writes `text` to `path` atomically (a temporary file renamed over it), as a secret or
// ConfigMap volume is updated.
void ReplaceFile(const std::string& path, const std::string& text);
std::string ReadFile(const std::string& path);

}  // namespace skinserve::testing
