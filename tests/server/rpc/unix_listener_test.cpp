// unix: addresses are accepted by the server itself (server/rpc/unix_listener.h), so that it
// knows each client's credentials; the rest must stay as it was with gRPC's own listener:
// a stale socket file is replaced, the file goes at shutdown, both spellings of the
// address work, an address that cannot be bound is a start-up error naming it, and TCP
// beside it keeps its port.
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "rpc/skin_server.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;

class SocketDir {
 public:
  SocketDir() {
    char name[] = "/tmp/skinserve-unix-XXXXXX";
    path_ = mkdtemp(name);
  }
  ~SocketDir() { std::filesystem::remove_all(path_); }
  std::string operator/(const std::string& file) const { return path_ + "/" + file; }

 private:
  std::string path_;
};

server::ServerOptions Options(std::vector<std::string> listen) {
  server::ServerOptions options;
  options.listen = std::move(listen);
  options.backends = {"serial"};
  options.default_backend = "serial";
  options.log_level = "warn";
  return options;
}

// A socket file left behind by a process that is gone.
void LeaveStaleSocket(const std::string& path) {
  const int fd = socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof(addr.sun_path) - 1);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  close(fd);
}

bool IsSocket(const std::string& path) {
  struct stat st = {};
  return lstat(path.c_str(), &st) == 0 && S_ISSOCK(st.st_mode);
}

TEST(UnixListenerTest, AStaleSocketIsReplacedBothSpellingsServeAndTheFilesGoAtShutdown) {
  SocketDir dir;
  const std::string stale = dir / "stale.sock", other = dir / "other.sock";
  LeaveStaleSocket(stale);
  auto started =
      server::SkinServer::Start(Options({"127.0.0.1:0", "unix:" + stale, "unix://" + other}));
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  auto& server = *started;
  EXPECT_GT(server->port(), 0) << "the TCP address's port is still reported";
  for (const std::string& target :
       {"unix:" + stale, "unix://" + other, "127.0.0.1:" + std::to_string(server->port())}) {
    client::SkinClient c(client::MakeChannel(target));
    EXPECT_TRUE(client::CheckHealth(c.channel(), 10s).ok()) << target;
    EXPECT_TRUE(c.ListBackends().ok()) << target;
  }
  server->Shutdown(0ms);
  EXPECT_FALSE(IsSocket(stale)) << "the socket file outlived the server";
  EXPECT_FALSE(IsSocket(other));
}

TEST(UnixListenerTest, AnAddressThatCannotBeBoundIsAStartUpErrorNamingIt) {
  SocketDir dir;
  const std::string file = dir / "a-file";
  std::ofstream(file) << "not a socket";
  for (const std::string& address : {std::string("unix:/nonexistent-skinserve-dir/grpc.sock"),
                                     "unix:" + file, "unix:" + std::string(120, 'x')}) {
    auto started = server::SkinServer::Start(Options({"127.0.0.1:0", address}));
    ASSERT_FALSE(started.ok()) << address;
    EXPECT_EQ(started.status().code(), StatusCode::kUnavailable) << started.status().ToString();
    EXPECT_NE(started.status().message().find("cannot listen on " + address), std::string::npos)
        << started.status().ToString();
  }
  EXPECT_FALSE(IsSocket(file)) << "a file that is no socket was replaced";
  EXPECT_TRUE(std::filesystem::exists(file));
}

}  // namespace
}  // namespace skinserve::testing
