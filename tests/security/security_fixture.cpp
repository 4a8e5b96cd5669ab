#include "security_fixture.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "skinserve/client/frame_stream.h"
#include "skinserve/model/mesh.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

const std::string& CertificateRoot() {
  static const std::string root = [] {
    const std::string dir = TemporaryFolder("certificates");
    for (const char* ca : {"a", "b"}) {
      const std::string command = fmt::format(
          "bash '{}' '{}/{}' operator renderer guest >/dev/null", SKINSERVE_MAKE_CERTS, dir, ca);
      if (std::system(command.c_str()) != 0) {
        ADD_FAILURE() << "scripts/make-dev-certs.sh failed: " << command;
      }
    }
    return dir;
  }();
  return root;
}

}  // namespace

std::string TemporaryFolder(const std::string& name) {
  const std::string dir =
      fmt::format("{}skinserve-security-{}-{}", ::testing::TempDir(), getpid(), name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string Certificate(const std::string& ca, const std::string& name, const std::string& ext) {
  return fmt::format("{}/{}/{}.{}", CertificateRoot(), ca, name, ext);
}

server::ServerOptions QuickServerOptions() {
  server::ServerOptions options;
  options.listen = {};
  options.backends = {"sse", "passthrough"};
  options.default_backend = "sse";
  options.threads = 1;
  options.log_level = "warn";
  options.tls_refresh_seconds = 1;
  options.authz_refresh_seconds = 1;
  return options;
}

void UseServerTls(server::ServerOptions* options, const std::string& ca, bool mutual) {
  options->tls_cert = Certificate(ca, "server", "pem");
  options->tls_key = Certificate(ca, "server", "key");
  options->tls_client_ca = mutual ? Certificate(ca, "ca", "pem") : "";
}

std::unique_ptr<server::SkinServer> StartServer(server::ServerOptions options) {
  options.listen.insert(options.listen.begin(), "127.0.0.1:0");
  auto started = server::SkinServer::Start(options);
  EXPECT_TRUE(started.ok()) << started.status().ToString();
  return started.ok() ? std::move(started).value() : nullptr;
}

client::ChannelOptions ClientTls(const std::string& trusted_ca, const std::string& client,
                                 const std::string& client_ca) {
  client::TlsFiles files{.ca = Certificate(trusted_ca, "ca", "pem")};
  if (!client.empty()) {
    const std::string& of = client_ca.empty() ? trusted_ca : client_ca;
    files.cert = Certificate(of, client, "pem");
    files.key = Certificate(of, client, "key");
  }
  auto options = client::ChannelOptionsFromFiles(files);
  EXPECT_TRUE(options.ok()) << options.status().ToString();
  return options.ok() ? *options : client::ChannelOptions{};
}

Status UploadSkinAndStream(client::SkinClient& client) {
  constexpr uint32_t kJoints = 12;
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 2000, .influences = 2, .joint_count = kJoints, .seed = 3});
  auto mesh = Mesh::Create(arrays);
  if (!mesh.ok()) return mesh.status();
  auto info = client.Upload(arrays);
  if (!info.ok()) return info.status();
  const auto right = [&](uint64_t frame, const client::FrameResult& result) {
    const Deviation d =
        CompareWithReference(**mesh, MakeSyntheticPalette(kJoints, 3, frame), result.positions, {});
    return d.within_tolerance()
               ? Status::Ok()
               : Internal(fmt::format("frame {} differs from the reference", frame));
  };
  client::FrameResult result;
  if (Status s = client.Skin(info->mesh_id(), "sse", MakeSyntheticPalette(kJoints, 3, 0), 0, false,
                             &result);
      !s.ok()) {
    return s;
  }
  if (Status s = right(0, result); !s.ok()) return s;
  Status first_error;
  client::StreamSummary summary;
  Status streamed = client::StreamFrames(
      client, {.mesh_id = info->mesh_id(), .backend = "sse", .frames = 20, .window = 4},
      [&](uint64_t f) { return MakeSyntheticPalette(kJoints, 3, f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        Status s = r.status.ok() ? right(r.frame, r) : r.status;
        if (!s.ok() && first_error.ok()) first_error = s;
      },
      &summary);
  if (!streamed.ok()) return streamed;
  if (!first_error.ok()) return first_error;
  if (summary.answered != 20)
    return Internal(fmt::format("{} of 20 frames answered", summary.answered));
  return Status::Ok();
}

void ReplaceFile(const std::string& path, const std::string& text) {
  const std::string temporary = path + ".new";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << text;
  }
  std::filesystem::rename(temporary, path);
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace skinserve::testing
