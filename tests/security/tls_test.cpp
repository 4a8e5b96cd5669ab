// TLS and mutual TLS on the gRPC port, with certificates made at test time: who is refused
// and how, who gets through, and certificate files rotated under a running server.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <thread>

#include "security_fixture.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

std::string TargetOf(const server::SkinServer& server) {
  return "127.0.0.1:" + std::to_string(server.port());
}

// One call that needs a working connection; its status says how the connection went.
Status Ask(const std::string& target, const client::ChannelOptions& options, int connection = 0) {
  client::SkinClient client(client::MakeChannel(target, options, connection),
                            {.deadline = std::chrono::milliseconds(5000)});
  return client.ListBackends().status();
}

TEST(TlsTest, PlaintextClientIsRefusedByATlsServer) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/false);
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const Status plaintext = Ask(TargetOf(*server), {});
  EXPECT_EQ(plaintext.code(), StatusCode::kUnavailable) << plaintext.ToString();
  EXPECT_FALSE(plaintext.message().empty());
  std::cout << "plaintext client against a TLS server: " << plaintext.ToString() << "\n";
  // TLS alone asks no certificate of the client.
  EXPECT_TRUE(Ask(TargetOf(*server), ClientTls("a")).ok());
}

TEST(TlsTest, ClientWithoutACertificateIsRefusedByAMutualTlsServer) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/true);
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const Status anonymous = Ask(TargetOf(*server), ClientTls("a"));
  EXPECT_EQ(anonymous.code(), StatusCode::kUnavailable) << anonymous.ToString();
  std::cout << "TLS client without a certificate against mutual TLS: " << anonymous.ToString()
            << "\n";
  // A certificate from another CA is refused too.
  const Status stranger = Ask(TargetOf(*server), ClientTls("a", "operator", "b"), 1);
  EXPECT_EQ(stranger.code(), StatusCode::kUnavailable) << stranger.ToString();
  EXPECT_EQ(Ask(TargetOf(*server), {}, 2).code(), StatusCode::kUnavailable);
  EXPECT_TRUE(Ask(TargetOf(*server), ClientTls("a", "renderer"), 3).ok());
}

TEST(TlsTest, ClientRefusesAServerItsCaDidNotSign) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/false);
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const Status distrusted = Ask(TargetOf(*server), ClientTls("b"));
  EXPECT_EQ(distrusted.code(), StatusCode::kUnavailable) << distrusted.ToString();
  std::cout << "client trusting another CA: " << distrusted.ToString() << "\n";
}

TEST(TlsTest, ServerNameIsCheckedAgainstTheCertificate) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/false);
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const std::string port = std::to_string(server->port());
  // The certificate names localhost, skinserve and 127.0.0.1.
  EXPECT_TRUE(Ask("localhost:" + port, ClientTls("a")).ok());
  client::ChannelOptions named = ClientTls("a");
  named.server_name = "skinserve";
  EXPECT_TRUE(Ask("127.0.0.1:" + port, named, 1).ok());
  named.server_name = "elsewhere.example";
  const Status wrong = Ask("127.0.0.1:" + port, named, 2);
  EXPECT_EQ(wrong.code(), StatusCode::kUnavailable) << wrong.ToString();
}

TEST(TlsTest, EveryCallWorksWithTheRightCertificate) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/true);
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  client::SkinClient client(client::MakeChannel(TargetOf(*server), ClientTls("a", "operator")));
  Status s = UploadSkinAndStream(client);
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_TRUE(client.GetServerStats().ok());
}

TEST(TlsTest, UnixSocketsStayPlaintextBesideATlsPort) {
  const std::string socket = TemporaryFolder("unix") + "/grpc.sock";
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/true);
  options.listen = {"unix:" + socket};
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  client::SkinClient local(client::MakeChannel("unix:" + socket));
  Status s = UploadSkinAndStream(local);
  EXPECT_TRUE(s.ok()) << s.ToString();
  // The TCP port beside it still wants a certificate; TLS over the socket is not spoken.
  EXPECT_EQ(Ask(TargetOf(*server), {}).code(), StatusCode::kUnavailable);
  client::ChannelOptions tls = ClientTls("a", "operator");
  tls.server_name = "localhost";
  EXPECT_EQ(Ask("unix:" + socket, tls, 1).code(), StatusCode::kUnavailable);
}

TEST(TlsTest, BadFilesAreStartUpErrorsNamingTheFlag) {
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/false);
  options.tls_key = "/nonexistent/server.key";
  options.listen = {"127.0.0.1:0"};
  auto missing = server::SkinServer::Start(options);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("--tls-key '/nonexistent/server.key'"),
            std::string::npos)
      << missing.status().ToString();

  options = QuickServerOptions();
  options.tls_client_ca = Certificate("a", "ca", "pem");
  options.listen = {"127.0.0.1:0"};
  auto alone = server::SkinServer::Start(options);
  ASSERT_FALSE(alone.ok());
  EXPECT_NE(alone.status().message().find("--tls-client-ca"), std::string::npos);

  options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/false);
  options.tls_cert = SKINSERVE_MAKE_CERTS;  // a file, but no certificate
  options.listen = {"127.0.0.1:0"};
  auto not_pem = server::SkinServer::Start(options);
  ASSERT_FALSE(not_pem.ok());
  EXPECT_NE(not_pem.status().message().find("no PEM block"), std::string::npos);

  auto client_side = client::ChannelOptionsFromFiles({.ca = "/nonexistent/ca.pem"});
  ASSERT_FALSE(client_side.ok());
  EXPECT_NE(client_side.status().message().find("--tls-ca '/nonexistent/ca.pem'"),
            std::string::npos);
}

// The server's certificate, key and client CA are replaced (as a Kubernetes Secret volume
// is) by those of another CA: within the refresh interval new connections see the new
// ones, while a stream opened before goes on answering on its connection.
TEST(TlsTest, RotatedFilesReachNewConnectionsWhileOpenStreamsGoOn) {
  const std::string dir = TemporaryFolder("rotation");
  const auto copy = [&](const std::string& ca, const std::string& name, const std::string& ext,
                        const std::string& to) {
    ReplaceFile(dir + "/" + to, ReadFile(Certificate(ca, name, ext)));
  };
  copy("a", "server", "pem", "tls.crt");
  copy("a", "server", "key", "tls.key");
  copy("a", "ca", "pem", "ca.crt");
  server::ServerOptions options = QuickServerOptions();
  options.tls_cert = dir + "/tls.crt";
  options.tls_key = dir + "/tls.key";
  options.tls_client_ca = dir + "/ca.crt";
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const std::string target = TargetOf(*server);

  client::SkinClient streaming(client::MakeChannel(target, ClientTls("a", "operator")));
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 2000, .joint_count = 12});
  auto info = streaming.Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  std::atomic<bool> stop{false}, rotated{false};
  std::atomic<uint64_t> after_rotation{0};
  client::StreamSummary summary;
  Status streamed;
  std::thread stream([&] {
    streamed = client::StreamFrames(
        streaming,
        {.mesh_id = info->mesh_id(),
         .backend = "sse",
         .frames = UINT64_MAX / 2,
         .window = 2,
         .max_reconnects = 0,
         .stop = &stop},
        [&](uint64_t f) {
          std::this_thread::sleep_for(2ms);  // a steady trickle, not a flood
          return MakeSyntheticPalette(12, 1, f);
        },
        [&](client::FrameResult& r, std::chrono::nanoseconds) {
          if (r.status.ok() && rotated.load()) after_rotation.fetch_add(1);
        },
        &summary);
  });
  std::this_thread::sleep_for(300ms);
  EXPECT_TRUE(Ask(target, ClientTls("a", "operator"), 1).ok());

  copy("b", "server", "pem", "tls.crt");
  copy("b", "server", "key", "tls.key");
  copy("b", "ca", "pem", "ca.crt");
  rotated.store(true);
  // New connections (each its own: connection ids differ) see CA b's files within the
  // refresh interval (1 s here; 60 s by default).
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  int connection = 10;
  bool switched = false;
  while (!switched && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(200ms);
    switched = Ask(target, ClientTls("b", "operator"), ++connection).ok();
  }
  EXPECT_TRUE(switched) << "CA b's client not let in 10 s after the rotation";
  const Status old_client = Ask(target, ClientTls("a", "operator"), ++connection);
  EXPECT_EQ(old_client.code(), StatusCode::kUnavailable) << old_client.ToString();
  const uint64_t before = after_rotation.load();
  std::this_thread::sleep_for(300ms);
  stop.store(true);
  stream.join();
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_GT(after_rotation.load(), before) << "the open stream stopped answering";
  EXPECT_EQ(summary.failed, 0u);
  EXPECT_EQ(summary.reconnects, 0u);
  std::cout << "rotation: the stream opened before it answered " << after_rotation.load()
            << " frames after it, none failed\n";
}

}  // namespace
}  // namespace skinserve::testing
