// The authorization policy under mutual TLS: the example policy of deploy/ allows and
// denies as written, principals are the clients' certificates, the file is re-read, and a
// policy that does not parse is a start-up error.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <thread>

#include "security_fixture.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

// deploy/authz-policy.json: health for everyone; skinning for renderer and operator;
// everything (DeleteMesh, GetServerStats, reflection) for the operator alone.
std::string ExamplePolicy() { return ReadFile(SKINSERVE_EXAMPLE_POLICY); }

class AuthzTest : public ::testing::Test {
 protected:
  void SetUp() override {
    policy_ = TemporaryFolder("authz") + "/policy.json";
    ReplaceFile(policy_, ExamplePolicy());
    server::ServerOptions options = QuickServerOptions();
    UseServerTls(&options, "a", /*mutual=*/true);
    options.authz_policy = policy_;
    server_ = StartServer(options);
    ASSERT_NE(server_, nullptr);
  }

  std::unique_ptr<client::SkinClient> As(const std::string& who) {
    return std::make_unique<client::SkinClient>(
        client::MakeChannel("127.0.0.1:" + std::to_string(server_->port()), ClientTls("a", who),
                            ++connection_),
        client::CallLimits{.deadline = 5000ms});
  }

  std::string policy_;
  std::unique_ptr<server::SkinServer> server_;
  int connection_ = 0;
};

TEST_F(AuthzTest, TheExamplePolicyAllowsAndDeniesAsWritten) {
  auto renderer = As("renderer");
  auto operator_ = As("operator");
  auto guest = As("guest");  // signed by the same CA, named by no rule

  // Skinning: renderer and operator.
  Status s = UploadSkinAndStream(*renderer);
  EXPECT_TRUE(s.ok()) << s.ToString();
  EXPECT_TRUE(operator_->ListBackends().ok());
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 500, .joint_count = 4});
  auto info = renderer->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();

  // DeleteMesh and GetServerStats: the operator alone.
  const Status stats = renderer->GetServerStats().status();
  EXPECT_EQ(stats.code(), StatusCode::kPermissionDenied) << stats.ToString();
  std::cout << "renderer GetServerStats: " << stats.ToString() << "\n";
  const Status deleted = renderer->DeleteMesh(info->mesh_id()).status();
  EXPECT_EQ(deleted.code(), StatusCode::kPermissionDenied) << deleted.ToString();
  EXPECT_TRUE(operator_->GetServerStats().ok());
  auto removed = operator_->DeleteMesh(info->mesh_id());
  ASSERT_TRUE(removed.ok()) << removed.status().ToString();
  EXPECT_TRUE(*removed);

  // A client of the right CA that no rule names: health, nothing else.
  EXPECT_EQ(guest->ListBackends().status().code(), StatusCode::kPermissionDenied);
  EXPECT_EQ(guest->Upload(arrays).status().code(), StatusCode::kPermissionDenied);
  EXPECT_TRUE(client::CheckHealth(guest->channel(), 5000ms).ok());
}

TEST_F(AuthzTest, AnEditedPolicyFileTakesEffectWithoutARestart) {
  auto renderer = As("renderer");
  ASSERT_EQ(renderer->GetServerStats().status().code(), StatusCode::kPermissionDenied);
  // The renderer may now read the stats too.
  std::string policy = ExamplePolicy();
  const std::string rule = "\"/skinserve.v1.Skinning/ListBackends\"";
  ASSERT_NE(policy.find(rule), std::string::npos);
  policy.replace(policy.find(rule), rule.size(),
                 rule + ", \"/skinserve.v1.Skinning/GetServerStats\"");
  ReplaceFile(policy_, policy);
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  Status stats = renderer->GetServerStats().status();
  while (!stats.ok() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(200ms);
    stats = renderer->GetServerStats().status();
  }
  EXPECT_TRUE(stats.ok()) << "10 s after the edit: " << stats.ToString();
  // DeleteMesh is still the operator's alone.
  EXPECT_EQ(renderer->DeleteMesh("0123").status().code(), StatusCode::kPermissionDenied);
  // A broken edit leaves the last good policy in force.
  ReplaceFile(policy_, "{ not json");
  std::this_thread::sleep_for(1500ms);
  EXPECT_TRUE(renderer->GetServerStats().ok());
  EXPECT_EQ(renderer->DeleteMesh("0123").status().code(), StatusCode::kPermissionDenied);
}

TEST(AuthzStartTest, AnInvalidPolicyIsAStartUpErrorNamingTheFlag) {
  const std::string path = TemporaryFolder("authz-invalid") + "/policy.json";
  ReplaceFile(path, R"({"name": "x", "allow_rules": [{"request": {"paths": ["*"]}}]})");
  server::ServerOptions options = QuickServerOptions();
  options.authz_policy = path;
  options.listen = {"127.0.0.1:0"};
  auto started = server::SkinServer::Start(options);
  ASSERT_FALSE(started.ok());
  EXPECT_NE(started.status().message().find("--authz-policy '" + path + "'"), std::string::npos)
      << started.status().ToString();
  std::cout << "invalid policy: " << started.status().ToString() << "\n";
}

}  // namespace
}  // namespace skinserve::testing
