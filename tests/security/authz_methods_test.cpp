// The methods an authorization policy governs: every method of every service declared in
// skinning.proto, walked from its descriptors (so a service or method added there is
// covered here without editing this test), is refused by a policy that allows nothing but
// health, naming the method; and a policy naming a method the server does not serve is
// refused when it loads, naming the rule, the path and what the service has. The example
// policy decides GpuRegions calls by the caller's certificate.
#include <gtest/gtest.h>

#include <fmt/format.h>
#include <google/protobuf/descriptor.h>
#include <grpcpp/generic/generic_stub.h>

#include "security/authz_policy.h"
#include "security_fixture.h"
#include "skinserve/client/frame_socket_client.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

// Every "/package.Service/Method" of the file that declares skinserve.v1.Skinning.
std::vector<std::string> SkinningProtoPaths() {
  const auto* skinning = google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(
      "skinserve.v1.Skinning");
  EXPECT_NE(skinning, nullptr);
  std::vector<std::string> paths;
  for (int s = 0; skinning != nullptr && s < skinning->file()->service_count(); ++s) {
    const auto* service = skinning->file()->service(s);
    for (int m = 0; m < service->method_count(); ++m) {
      paths.push_back(fmt::format("/{}/{}", service->full_name(), service->method(m)->name()));
    }
  }
  return paths;
}

// Calls `path` whatever its kind: one empty message (a valid request of every type), then
// half-close, read to the end; the call's status.
grpc::Status CallWithAnEmptyRequest(const std::shared_ptr<grpc::Channel>& channel,
                                    const std::string& path) {
  grpc::GenericStub stub(channel);
  grpc::CompletionQueue queue;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  const auto wait = [&queue] {
    void* tag = nullptr;
    bool ok = false;
    EXPECT_TRUE(queue.Next(&tag, &ok));
    return ok;
  };
  std::unique_ptr<grpc::GenericClientAsyncReaderWriter> call =
      stub.PrepareCall(&context, path, &queue);
  call->StartCall(nullptr);
  wait();
  grpc::Slice nothing(std::string{});
  const grpc::ByteBuffer empty(&nothing, 1);
  call->Write(empty, nullptr);
  wait();
  call->WritesDone(nullptr);
  wait();
  grpc::ByteBuffer answer;
  do {
    call->Read(&answer, nullptr);
  } while (wait());
  grpc::Status status;
  call->Finish(&status, nullptr);
  wait();
  queue.Shutdown();
  return status;
}

TEST(AuthzMethodsTest, EveryMethodOfEveryServiceIsGovernedByThePolicy) {
  const std::string folder = TemporaryFolder("authz-methods");
  const std::string policy = folder + "/policy.json";
  ReplaceFile(policy, R"({"name": "health-only", "allow_rules": [{"name": "health",
    "request": {"paths": ["/grpc.health.v1.Health/*"]}}]})");
  server::ServerOptions options = QuickServerOptions();
  options.authz_policy = policy;
  options.shm_dir = folder;                     // shared-memory regions on
  options.gpu_fd_socket = folder + "/fd.sock";  // the GpuRegions service on
  options.frame_socket = folder + "/frames.sock";
  options.listen = {"unix:" + folder + "/grpc.sock"};
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  const auto channel = client::MakeChannel("unix:" + folder + "/grpc.sock");
  const std::vector<std::string> paths = SkinningProtoPaths();
  ASSERT_GT(paths.size(), 3u);
  for (const std::string& path : paths) {
    const grpc::Status status = CallWithAnEmptyRequest(channel, path);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED)
        << path << ": " << status.error_message();
    EXPECT_EQ(status.error_message(),
              fmt::format("{} is not allowed for an unauthenticated client by the "
                          "authorization policy 'health-only' (no allow rule matches; "
                          "--authz-policy)",
                          path));
  }
  EXPECT_TRUE(client::CheckHealth(*channel, 5000ms).ok());
  // The frame socket serves StreamSkin's requests: the policy's StreamSkin rule governs it.
  auto frames = client::FrameSocketClient::Connect(folder + "/frames.sock");
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  (*frames)->Write(v1::SkinRequest());
  grpc::ByteBuffer part;
  EXPECT_FALSE((*frames)->Read(&part)) << "the frame socket answered a frame";
  EXPECT_EQ((*frames)->Finish().code(), StatusCode::kPermissionDenied)
      << (*frames)->Finish().ToString();
  EXPECT_EQ((*frames)->Finish().message(),
            "/skinserve.v1.Skinning/StreamSkin is not allowed for an unauthenticated client by "
            "the authorization policy 'health-only' (no allow rule matches; --authz-policy)");
}

// The example policy over mutual TLS decides GpuRegions calls by principal as it does the
// others: a guest is refused by the policy; the renderer it allows reaches the service,
// which refuses TCP itself (a descriptor cannot cross TCP).
TEST(AuthzMethodsTest, TheExamplePolicyDecidesGpuRegionCallsByPrincipal) {
  const std::string folder = TemporaryFolder("authz-gpu-principals");
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/true);
  options.authz_policy = SKINSERVE_EXAMPLE_POLICY;
  options.gpu_fd_socket = folder + "/fd.sock";
  auto server = StartServer(options);
  ASSERT_NE(server, nullptr);
  int connection = 0;
  const auto list_as = [&](const std::string& who) {
    auto stub = v1::GpuRegions::NewStub(client::MakeChannel(
        "127.0.0.1:" + std::to_string(server->port()), ClientTls("a", who), ++connection));
    grpc::ClientContext context;
    v1::ListGpuRegionsResponse list;
    return stub->ListGpuRegions(&context, {}, &list);
  };
  const grpc::Status guest = list_as("guest");
  EXPECT_EQ(guest.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(guest.error_message(),
            "/skinserve.v1.GpuRegions/ListGpuRegions is not allowed for "
            "spiffe://skinserve/guest by the authorization policy 'skinserve' (no allow rule "
            "matches; --authz-policy)");
  const grpc::Status renderer = list_as("renderer");
  EXPECT_EQ(renderer.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(renderer.error_message().find("authorization policy"), std::string::npos)
      << renderer.error_message();
  EXPECT_NE(renderer.error_message().find("not served over TCP"), std::string::npos)
      << renderer.error_message();
}

TEST(AuthzMethodsTest, APathNamingNoServedMethodIsRefusedAtLoad) {
  const auto refused = [](const std::string& path) {
    return server::AuthorizationPolicy::Parse(fmt::format(
        R"({{"name": "p", "allow_rules": [{{"name": "ok", "request": {{"paths": ["*"]}}}},
           {{"name": "typo", "request": {{"paths": ["/grpc.health.v1.Health/Check", "{}"]}}}}]}})",
        path));
  };
  auto typo = refused("/skinserve.v1.GpuRegions/RegisterGpuRegions");
  ASSERT_FALSE(typo.ok());
  EXPECT_EQ(typo.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(typo.status().message(),
            "allow_rules[1].request.paths[1]: \"/skinserve.v1.GpuRegions/RegisterGpuRegions\" "
            "matches no method this server serves (skinserve.v1.GpuRegions has "
            "ListGpuRegions, RegisterGpuRegion, UnregisterGpuRegion)");
  auto service = refused("/skinserve.v2.Skinning/*");
  ASSERT_FALSE(service.ok());
  EXPECT_NE(service.status().message().find("\"/skinserve.v2.Skinning/*\" matches no method"),
            std::string::npos)
      << service.status().message();
  EXPECT_NE(service.status().message().find("skinserve.v1.GpuRegions, skinserve.v1.Skinning"),
            std::string::npos)
      << service.status().message();
  EXPECT_FALSE(refused("*Regionz").ok());
  // What names served methods loads: each GpuRegions method, its service, a suffix,
  // the Skinning ones and gRPC's own.
  for (const char* path :
       {"/skinserve.v1.GpuRegions/RegisterGpuRegion",
        "/skinserve.v1.GpuRegions/UnregisterGpuRegion", "/skinserve.v1.GpuRegions/ListGpuRegions",
        "/skinserve.v1.GpuRegions/*", "*GpuRegion", "/skinserve.v1.Skinning/RegisterRegion",
        "/grpc.health.v1.Health/Watch",
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo"}) {
    auto parsed = refused(path);
    EXPECT_TRUE(parsed.ok()) << path << ": " << parsed.status().ToString();
  }
}

TEST(AuthzMethodsTest, APolicyNamingAnUnknownMethodStopsTheServerAtStart) {
  const std::string path = TemporaryFolder("authz-unknown") + "/policy.json";
  ReplaceFile(path, R"({"name": "x", "allow_rules": [{"name": "gpu",
    "request": {"paths": ["/skinserve.v1.GpuRegions/RegisterGpuRegions"]}}]})");
  server::ServerOptions options = QuickServerOptions();
  options.authz_policy = path;
  options.listen = {"127.0.0.1:0"};
  auto started = server::SkinServer::Start(options);
  ASSERT_FALSE(started.ok());
  EXPECT_EQ(started.status().message(),
            fmt::format("--authz-policy '{}': allow_rules[0].request.paths[0]: "
                        "\"/skinserve.v1.GpuRegions/RegisterGpuRegions\" matches no method "
                        "this server serves (skinserve.v1.GpuRegions has ListGpuRegions, "
                        "RegisterGpuRegion, UnregisterGpuRegion)",
                        path));
}

}  // namespace
}  // namespace skinserve::testing
