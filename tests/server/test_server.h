// A real skinserve server in this process, on an ephemeral loopback port, and a client.
#pragma once

#include <gtest/gtest.h>

#include <vector>

#include "skin_server.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {

struct TestServer {
  std::unique_ptr<server::SkinServer> server;
  std::unique_ptr<client::SkinClient> client;
  std::string target;

  explicit TestServer(server::ServerOptions options = {}) {
    options.listen = {"127.0.0.1:0"};
    options.log_level = "warn";
    auto started = server::SkinServer::Start(options);
    EXPECT_TRUE(started.ok()) << started.status().ToString();
    server = std::move(started).value();
    target = "127.0.0.1:" + std::to_string(server->port());
    client = std::make_unique<client::SkinClient>(client::MakeChannel(target));
  }
};

// Sends `messages` as one UploadMesh call through the raw stub (for uploads the client
// library would refuse or shape itself); the server's MeshInfo or its status.
inline Result<v1::MeshInfo> RawUploadMesh(client::SkinClient& c,
                                          const std::vector<v1::UploadMeshRequest>& messages) {
  grpc::ClientContext context;
  v1::MeshInfo info;
  auto writer = c.stub().UploadMesh(&context, &info);
  for (const auto& m : messages) {
    if (!writer->Write(m)) break;
  }
  writer->WritesDone();
  if (Status s = wire::FromGrpc(writer->Finish()); !s.ok()) return s;
  return info;
}

}  // namespace skinserve::testing
