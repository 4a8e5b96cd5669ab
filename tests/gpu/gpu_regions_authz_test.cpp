// The --authz-policy over the GpuRegions service, on a real server (in this process) on
// PoCL, called over its Unix socket: a deny rule naming RegisterGpuRegion refuses it
// PERMISSION_DENIED naming the method and the rule, before the service takes the handed
// fd's token; a policy that allows it lets the call through to the service, which then
// refuses FAILED_PRECONDITION: on PoCL naming the OpenCL extension it lacks, on a GPU that
// imports (the H200) naming the test's device_uuid (zeros) as not its device's.
#include <fmt/format.h>
#include <sys/mman.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "../server/test_server.h"
#include "skinserve/client/gpu_fd_handoff.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::testing {
namespace {

// The call reached the service, which refused the import: PoCL has no importable memory;
// a GPU that has it refuses the test's device_uuid (zeros), which is not its device's.
void ExpectRefusedByTheService(const Status& s) {
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
  EXPECT_TRUE(s.message().find("lacks cl_khr_external_memory") != std::string::npos ||
              s.message().find("is not the opencl backend's device") != std::string::npos)
      << s.message();
}

using namespace std::chrono_literals;

constexpr char kRegister[] = "/skinserve.v1.GpuRegions/RegisterGpuRegion";

// Everything allowed to every client but RegisterGpuRegion.
constexpr char kDenyRegister[] = R"({"name": "no-gpu-registration",
  "allow_rules": [{"name": "all", "request": {"paths": ["*"]}}],
  "deny_rules": [{"name": "no_gpu_registration",
                  "request": {"paths": ["/skinserve.v1.GpuRegions/RegisterGpuRegion"]}}]})";
// The GpuRegions methods alone, to every client.
constexpr char kGpuRegionsOnly[] = R"({"name": "gpu-regions-only",
  "allow_rules": [{"name": "gpu_regions", "request": {"paths": ["/skinserve.v1.GpuRegions/*"]}}]})";

class GpuRegionsAuthzTest : public ::testing::Test {
 protected:
  void Start(const std::string& policy) {
    char name[] = "/tmp/skinserve-gpu-authz-XXXXXX";
    dir_ = mkdtemp(name);
    policy_ = dir_ + "/policy.json";
    WritePolicy(policy);
    server::ServerOptions options;
    options.gpu_fd_socket = dir_ + "/fd.sock";
    options.authz_policy = policy_;
    options.authz_refresh_seconds = 1;
    server_ = std::make_unique<TestServer>(options, Transport::kUnixSocket);
    stub_ = v1::GpuRegions::NewStub(client::MakeChannel(server_->target));
  }
  void TearDown() override {
    stub_.reset();
    server_.reset();
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }
  // Atomically, as a ConfigMap volume is updated.
  void WritePolicy(const std::string& text) {
    std::ofstream(policy_ + ".new") << text;
    std::filesystem::rename(policy_ + ".new", policy_);
  }
  std::string HandOver() {
    const int fd = memfd_create("stand-in", MFD_CLOEXEC);
    EXPECT_EQ(ftruncate(fd, 1 << 20), 0);
    Result<std::string> token = client::HandOverGpuFd(dir_ + "/fd.sock", fd);
    close(fd);
    EXPECT_TRUE(token.ok()) << token.status().ToString();
    return token.ok() ? *token : "";
  }
  Status Register(const std::string& token) {
    v1::RegisterGpuRegionRequest request;
    request.set_name("vertices");
    request.set_fd_token(token);
    request.set_byte_size(1 << 20);
    request.set_device_uuid(std::string(16, '\0'));
    request.set_backend("opencl");
    grpc::ClientContext context;
    v1::GpuRegionInfo info;
    return wire::FromGrpc(stub_->RegisterGpuRegion(&context, request, &info));
  }
  Status List() {
    grpc::ClientContext context;
    v1::ListGpuRegionsResponse list;
    return wire::FromGrpc(stub_->ListGpuRegions(&context, {}, &list));
  }

  std::string dir_, policy_;
  std::unique_ptr<TestServer> server_;
  std::unique_ptr<v1::GpuRegions::Stub> stub_;
};

TEST_F(GpuRegionsAuthzTest, ADenyRuleRefusesRegisterGpuRegionNamingTheMethod) {
  Start(kDenyRegister);
  const std::string token = HandOver();
  const Status denied = Register(token);
  ASSERT_EQ(denied.code(), StatusCode::kPermissionDenied) << denied.ToString();
  EXPECT_NE(denied.message().find(fmt::format("{} is not allowed for an unauthenticated client "
                                              "by the authorization policy 'no-gpu-registration' "
                                              "(deny rule 'no_gpu_registration'",
                                              kRegister)),
            std::string::npos)
      << denied.message();
  std::cout << "denied: " << denied.ToString() << "\n";
  // The rule names one method: the others of the service still answer.
  EXPECT_TRUE(List().ok()) << List().ToString();
  // Refused before the service: the token is still unused, and good once the policy allows.
  WritePolicy(kGpuRegionsOnly);
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  Status s = Register(token);
  while (s.code() == StatusCode::kPermissionDenied && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(100ms);
    s = Register(token);
  }
  ExpectRefusedByTheService(s);
}

TEST_F(GpuRegionsAuthzTest, APolicyAllowingItLetsRegisterGpuRegionReachTheService) {
  Start(kGpuRegionsOnly);
  const Status s = Register(HandOver());
  ExpectRefusedByTheService(s);
  EXPECT_TRUE(List().ok()) << List().ToString();
  // The policy is in force: what it does not list is refused.
  const Status backends = server_->client->ListBackends().status();
  EXPECT_EQ(backends.code(), StatusCode::kPermissionDenied) << backends.ToString();
  EXPECT_NE(backends.message().find("/skinserve.v1.Skinning/ListBackends is not allowed"),
            std::string::npos)
      << backends.message();
}

}  // namespace
}  // namespace skinserve::testing
