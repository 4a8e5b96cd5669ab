// GPU regions on a real server (in this process) on PoCL, where nothing can be imported:
// the fd handed over --gpu-fd-socket for a one-time token bound to the handing process;
// RegisterGpuRegion refused FAILED_PRECONDITION naming the missing extension (opencl) or
// the backend (any other); a token of another process, a used token, a bad UUID, TCP and
// frames naming GPU regions that do not exist all refused with what is wrong.
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstring>

#include "../server/test_server.h"
#include "skinserve/client/gpu_fd_handoff.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::testing {
namespace {

struct GpuServer {
  std::unique_ptr<TestServer> server;
  std::string fd_socket;
  explicit GpuServer(bool gpu_on = true) {
    char name[] = "/tmp/skinserve-gpu-fd-XXXXXX";
    dir_ = mkdtemp(name);
    fd_socket = dir_ + "/fd.sock";
    server::ServerOptions options;
    if (gpu_on) options.gpu_fd_socket = fd_socket;
    server = std::make_unique<TestServer>(options, Transport::kUnixSocket);
  }
  ~GpuServer() {
    server.reset();
    std::filesystem::remove_all(dir_);
  }
  std::unique_ptr<v1::GpuRegions::Stub> Stub() {
    return v1::GpuRegions::NewStub(client::MakeChannel(server->target));
  }

 private:
  std::string dir_;
};

int Memfd() {
  const int fd = memfd_create("stand-in", MFD_CLOEXEC);
  EXPECT_GE(fd, 0);
  EXPECT_EQ(ftruncate(fd, 1 << 20), 0);
  return fd;
}

Result<v1::GpuRegionInfo> Register(v1::GpuRegions::Stub& stub, const std::string& token,
                                   const std::string& backend, std::size_t uuid_bytes = 16) {
  v1::RegisterGpuRegionRequest request;
  request.set_name("vertices");
  request.set_fd_token(token);
  request.set_byte_size(1 << 20);
  request.set_device_uuid(std::string(uuid_bytes, '\0'));
  request.set_backend(backend);
  grpc::ClientContext context;
  v1::GpuRegionInfo info;
  if (Status s = wire::FromGrpc(stub.RegisterGpuRegion(&context, request, &info)); !s.ok()) {
    return s;
  }
  return info;
}

std::string HandOver(const std::string& socket) {
  const int fd = Memfd();
  Result<std::string> token = client::HandOverGpuFd(socket, fd);
  close(fd);
  EXPECT_TRUE(token.ok()) << token.status().ToString();
  return token.ok() ? *token : "";
}

// Why the opencl backend refused the test's import: on PoCL the extension it lacks (the
// first of `pocl_words`' list); on a GPU that imports (the H200, scripts/gpu-region-test.sh's
// machine) the test's device_uuid of zeros, which is not its device's.
void ExpectImportRefused(const Status& refused, const std::string& pocl_words) {
  EXPECT_EQ(refused.code(), StatusCode::kFailedPrecondition) << refused.ToString();
  EXPECT_TRUE(refused.message().find(pocl_words) != std::string::npos ||
              refused.message().find("is not the opencl backend's device") != std::string::npos)
      << refused.message();
}

TEST(GpuRegionsTest, OpenClOnPoclIsRefusedNamingTheMissingExtension) {
  GpuServer gpu;
  auto stub = gpu.Stub();
  const std::string token = HandOver(gpu.fd_socket);
  EXPECT_EQ(token.size(), 32u);
  auto refused = Register(*stub, token, "opencl");
  ASSERT_FALSE(refused.ok());
  ExpectImportRefused(refused.status(), "lacks cl_khr_external_memory");
  // The token was used: once only.
  auto again = Register(*stub, token, "opencl");
  EXPECT_EQ(again.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(again.status().message().find("unknown to this client"), std::string::npos)
      << again.status().message();
  // Nothing is left reserved by the failed import.
  grpc::ClientContext context;
  v1::ListGpuRegionsResponse list;
  ASSERT_TRUE(stub->ListGpuRegions(&context, {}, &list).ok());
  EXPECT_EQ(list.regions_size(), 0);
  EXPECT_EQ(list.imported_bytes(), 0u);
}

TEST(GpuRegionsTest, ASemaphoreTokenIsUsedAndItsRefusalNamed) {
  GpuServer gpu;
  auto stub = gpu.Stub();
  const std::string memory = HandOver(gpu.fd_socket), semaphore = HandOver(gpu.fd_socket);
  v1::RegisterGpuRegionRequest request;
  request.set_name("vertices");
  request.set_fd_token(memory);
  request.set_semaphore_fd_token(semaphore);
  request.set_byte_size(1 << 20);
  request.set_device_uuid(std::string(16, '\0'));
  request.set_backend("opencl");
  {
    grpc::ClientContext context;
    v1::GpuRegionInfo info;
    const Status refused = wire::FromGrpc(stub->RegisterGpuRegion(&context, request, &info));
    // PoCL: the first extension of all it lacks, for memory with a semaphore.
    ExpectImportRefused(refused, "with a semaphore: it lacks cl_khr_external_memory");
  }
  // Both tokens were used: the semaphore's is unknown now, even as a buffer's.
  auto again = Register(*stub, semaphore, "opencl");
  EXPECT_EQ(again.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(again.status().message().find("unknown to this client"), std::string::npos)
      << again.status().message();
  // A semaphore token never handed over: named, and the buffer's token is used up too.
  request.set_fd_token(HandOver(gpu.fd_socket));
  request.set_semaphore_fd_token(std::string(32, 'f'));
  grpc::ClientContext context;
  v1::GpuRegionInfo info;
  const Status unknown = wire::FromGrpc(stub->RegisterGpuRegion(&context, request, &info));
  EXPECT_EQ(unknown.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(unknown.message().rfind("semaphore_fd_token: ", 0), 0u) << unknown.message();
  grpc::ClientContext list_context;
  v1::ListGpuRegionsResponse list;
  ASSERT_TRUE(stub->ListGpuRegions(&list_context, {}, &list).ok());
  EXPECT_EQ(list.regions_size(), 0);
}

TEST(GpuRegionsTest, OtherBackendsCannotImport) {
  GpuServer gpu;
  auto stub = gpu.Stub();
  auto refused = Register(*stub, HandOver(gpu.fd_socket), "simd");
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("backend 'simd' cannot write into GPU memory"),
            std::string::npos)
      << refused.status().message();
}

TEST(GpuRegionsTest, DeviceUuidMustBeSixteenBytes) {
  GpuServer gpu;
  auto stub = gpu.Stub();
  auto refused = Register(*stub, HandOver(gpu.fd_socket), "opencl", 15);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("device_uuid holds 15 bytes"), std::string::npos);
}

TEST(GpuRegionsTest, TokenOfAnotherProcessIsUnknown) {
  GpuServer gpu;
  int pipe_fds[2];
  ASSERT_EQ(pipe(pipe_fds), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // another process of this uid hands an fd over
    const int fd = memfd_create("child", 0);
    Result<std::string> token = client::HandOverGpuFd(gpu.fd_socket, fd);
    const std::string text = token.ok() ? *token : "";
    _exit(write(pipe_fds[1], text.data(), text.size()) == static_cast<ssize_t>(text.size()) &&
                  token.ok()
              ? 0
              : 1);
  }
  close(pipe_fds[1]);
  char buffer[64] = {};
  const ssize_t n = read(pipe_fds[0], buffer, sizeof(buffer));
  close(pipe_fds[0]);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ASSERT_EQ(n, 32);
  auto stub = gpu.Stub();
  auto refused = Register(*stub, std::string(buffer, 32), "opencl");
  EXPECT_EQ(refused.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("unknown to this client"), std::string::npos)
      << refused.status().message();
}

TEST(GpuRegionsTest, OverTcpThereAreNoGpuRegions) {
  GpuServer gpu;
  auto stub = v1::GpuRegions::NewStub(
      client::MakeChannel(fmt::format("127.0.0.1:{}", gpu.server->server->port())));
  auto refused = Register(*stub, HandOver(gpu.fd_socket), "opencl");
  EXPECT_EQ(refused.status().code(), StatusCode::kPermissionDenied);
}

TEST(GpuRegionsTest, HandoffWithoutAnFdIsRefused) {
  GpuServer gpu;
  const int s = socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  std::strcpy(addr.sun_path, gpu.fd_socket.c_str());
  ASSERT_EQ(connect(s, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0);
  ASSERT_EQ(write(s, "SKGPUFD1", 8), 8);
  char answer[256] = {};
  ASSERT_GT(read(s, answer, sizeof(answer) - 1), 0);
  close(s);
  EXPECT_NE(std::string(answer).find("ERR expected the 8 bytes 'SKGPUFD1' with exactly one file "
                                     "descriptor"),
            std::string::npos)
      << answer;
}

// A frame naming a GPU region: refused when there is none of that name, or when GPU
// regions are off.
Status SkinIntoGpuRegion(TestServer& server, const std::string& region) {
  auto mesh = server.client->Upload(MakeSyntheticMesh({.vertex_count = 500}));
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  v1::SkinRequest request;
  request.set_mesh_id(mesh->mesh_id());
  request.set_backend("opencl");
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  request.mutable_output()->set_region(region);
  request.mutable_output()->set_gpu(true);
  grpc::ClientContext context;
  auto reader = server.client->stub().Skin(&context, request);
  v1::SkinResponse part;
  Status frame_error;
  while (reader->Read(&part)) {
    if (part.has_error()) {
      frame_error = Status(static_cast<StatusCode>(part.error().code()), part.error().message());
    }
  }
  if (Status s = wire::FromGrpc(reader->Finish()); !s.ok()) return s;
  return frame_error;
}

TEST(GpuRegionsTest, FramesNamingNoGpuRegionAreRefused) {
  GpuServer on;
  Status s = SkinIntoGpuRegion(*on.server, "nope");
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("no GPU region named 'nope'"), std::string::npos) << s.message();
  GpuServer off(/*gpu_on=*/false);
  s = SkinIntoGpuRegion(*off.server, "nope");
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("GPU regions are off"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace skinserve::testing
