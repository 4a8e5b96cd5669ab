// --reflection=false takes server reflection away; the health service answers readiness
// ("" and the service's name) and liveness ("liveness") separately.
#include <gtest/gtest.h>

#include "security_fixture.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

// One ServerReflectionInfo exchange asking for the list of services (field 7,
// list_services = ""): the answer's bytes, or the call's status when it fails.
grpc::Status ListServicesByReflection(const std::string& target, std::string* answer) {
  auto channel = client::MakeChannel(target);
  const std::string method = "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo";
  const grpc::internal::RpcMethod rpc(method.c_str(), grpc::internal::RpcMethod::BIDI_STREAMING,
                                      channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 5s);
  std::unique_ptr<grpc::ClientReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>> call(
      grpc::internal::ClientReaderWriterFactory<grpc::ByteBuffer, grpc::ByteBuffer>::Create(
          channel.get(), rpc, &context));
  const char request[] = {0x3a, 0x00};
  grpc::Slice slice(request, sizeof(request));
  call->Write(grpc::ByteBuffer(&slice, 1));
  call->WritesDone();
  grpc::ByteBuffer response;
  while (call->Read(&response)) {
    std::vector<grpc::Slice> slices;
    (void)response.Dump(&slices);
    for (const grpc::Slice& s : slices)
      answer->append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  return call->Finish();
}

TEST(ReflectionTest, OnByDefaultAndOffWhenAsked) {
  auto on = StartServer(QuickServerOptions());
  ASSERT_NE(on, nullptr);
  std::string services;
  grpc::Status listed =
      ListServicesByReflection("127.0.0.1:" + std::to_string(on->port()), &services);
  EXPECT_TRUE(listed.ok()) << listed.error_message();
  EXPECT_NE(services.find("skinserve.v1.Skinning"), std::string::npos);

  server::ServerOptions options = QuickServerOptions();
  options.reflection = false;
  auto off = StartServer(options);
  ASSERT_NE(off, nullptr);
  services.clear();
  listed = ListServicesByReflection("127.0.0.1:" + std::to_string(off->port()), &services);
  EXPECT_EQ(listed.error_code(), grpc::StatusCode::UNIMPLEMENTED) << listed.error_message();
  EXPECT_EQ(services.find("skinserve.v1.Skinning"), std::string::npos);
}

TEST(HealthTest, ReadinessAndLivenessAreSeparateNames) {
  auto server = StartServer(QuickServerOptions());
  ASSERT_NE(server, nullptr);
  auto channel = client::MakeChannel("127.0.0.1:" + std::to_string(server->port()));
  EXPECT_TRUE(client::CheckHealth(*channel, 5000ms).ok());
  EXPECT_TRUE(client::CheckHealth(*channel, 5000ms, "skinserve.v1.Skinning").ok());
  EXPECT_TRUE(client::CheckHealth(*channel, 5000ms, "liveness").ok());
  const Status unknown = client::CheckHealth(*channel, 5000ms, "no.such.Service");
  EXPECT_FALSE(unknown.ok());
}

}  // namespace
}  // namespace skinserve::testing
