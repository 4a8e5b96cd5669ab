// A real skinserve server in this process, on an ephemeral loopback port, and a client.
// Shared-memory regions are served to Unix-socket clients only (by default): tests that
// register regions ask for kUnixSocket, and the client talks to the server's socket.
#pragma once

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <vector>

#include "rpc/skin_server.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {

enum class Transport { kTcp, kUnixSocket };

struct TestServer {
  std::unique_ptr<server::SkinServer> server;
  std::unique_ptr<client::SkinClient> client;
  std::string target;      // what `client` talks to
  std::string socket_dir;  // kUnixSocket: the socket's folder (removed at the end)

  explicit TestServer(server::ServerOptions options = {}, Transport transport = Transport::kTcp) {
    options.listen = {"127.0.0.1:0"};
    if (transport == Transport::kUnixSocket) {
      char name[] = "/tmp/skinserve-test-sock-XXXXXX";
      socket_dir = mkdtemp(name);
      options.listen.push_back("unix:" + socket_dir + "/grpc.sock");
    }
    options.log_level = "warn";
    auto started = server::SkinServer::Start(options);
    EXPECT_TRUE(started.ok()) << started.status().ToString();
    server = std::move(started).value();
    target = transport == Transport::kUnixSocket ? "unix:" + socket_dir + "/grpc.sock"
                                                 : "127.0.0.1:" + std::to_string(server->port());
    client = std::make_unique<client::SkinClient>(client::MakeChannel(target));
  }
  ~TestServer() {
    client.reset();
    server.reset();
    if (!socket_dir.empty()) std::filesystem::remove_all(socket_dir);
  }
  TestServer(const TestServer&) = delete;
  TestServer& operator=(const TestServer&) = delete;
};

// The server's available backends that skin (every one but `passthrough`), by id.
inline std::vector<std::string> SkinningBackends(client::SkinClient& client) {
  std::vector<std::string> ids;
  auto list = client.ListBackends();
  EXPECT_TRUE(list.ok()) << list.status().ToString();
  if (!list.ok()) return ids;
  for (const auto& b : list->backends()) {
    if (b.available() && b.id() != "passthrough") ids.push_back(b.id());
  }
  return ids;
}

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
