// A real skinserve server in this process, on an ephemeral loopback port, and a client.
#pragma once

#include <gtest/gtest.h>

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

}  // namespace skinserve::testing
