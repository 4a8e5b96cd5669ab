// Shared-memory regions belong to the peer that registered them (issue 42): against a real
// server, every attack of the issue from a second peer - another uid or another process on
// the Unix socket (skinserve_region_peer, run as uid 65534), another certificate over
// mutual TLS, and plain TCP - while the owner keeps skinning into its region, every frame
// checked against the float64 reference. Another peer's list shows nothing of the owner's,
// its frames naming the owner's regions fail and leave their bytes alone, its unregisters
// fail, its registrations of files registered already or owned by another uid fail, and
// over TCP no error says whether a file exists or its size. Opens never block.
#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <set>
#include <sstream>
#include <thread>

#include "security_fixture.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/model/mesh.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::testing {
namespace {

using namespace std::chrono_literals;
using client::SharedMemoryRegion;

constexpr std::byte kCanary{0xA5};
constexpr uid_t kOtherUid = 65534;  // nobody: the second peer's uid
constexpr uint32_t kVertices = 2000;

// The regions' folder in /dev/shm, writable by every uid and sticky, as /dev/shm is; and a
// folder for the server's socket that every uid may reach.
class Folders {
 public:
  Folders() {
    char shm[] = "/dev/shm/skinserve-owners-XXXXXX";
    shm_ = mkdtemp(shm);
    chmod(shm_.c_str(), 01777);
    char sock[] = "/tmp/skinserve-owners-sock-XXXXXX";
    socket_dir_ = mkdtemp(sock);
    chmod(socket_dir_.c_str(), 0755);
  }
  ~Folders() {
    std::filesystem::remove_all(shm_);
    std::filesystem::remove_all(socket_dir_);
  }
  const std::string& shm() const { return shm_; }
  std::string socket() const { return socket_dir_ + "/grpc.sock"; }
  std::string unix_target() const { return "unix:" + socket(); }
  std::string frame_socket() const { return socket_dir_ + "/frames.sock"; }

 private:
  std::string shm_, socket_dir_;
};

// A server with shared memory in `folders` on its Unix socket (which any uid may use) and
// on 127.0.0.1:0 (TCP).
std::unique_ptr<server::SkinServer> StartShmServer(const Folders& folders,
                                                   server::ServerOptions options) {
  options.shm_dir = folders.shm();
  options.listen.push_back("unix:" + folders.socket());
  auto server = StartServer(options);
  if (server != nullptr) chmod(folders.socket().c_str(), 0666);
  return server;
}

std::string TcpTarget(const server::SkinServer& server) {
  return fmt::format("127.0.0.1:{}", server.port());
}

std::unique_ptr<SharedMemoryRegion> MakeRegion(const Folders& folders, const std::string& prefix,
                                               uint64_t bytes) {
  auto region =
      SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey(prefix), bytes, folders.shm());
  EXPECT_TRUE(region.ok()) << region.status().ToString();
  std::memset(region.value()->bytes().data(), static_cast<int>(kCanary), bytes);
  return std::move(region).value();
}

bool AllCanary(const SharedMemoryRegion& region) {
  const auto bytes = region.bytes();
  return std::all_of(bytes.begin(), bytes.end(), [](std::byte b) { return b == kCanary; });
}

Status Register(client::SkinClient& c, const std::string& name, const std::string& key,
                uint64_t bytes) {
  v1::RegisterRegionRequest request;
  request.set_name(name);
  request.set_key(key);
  request.set_byte_size(bytes);
  grpc::ClientContext context;
  v1::RegionInfo info;
  return wire::FromGrpc(c.stub().RegisterRegion(&context, request, &info));
}

// One frame of `mesh_id` named into region `name` at offset 0 (the raw stub: the client
// library would want a mapping of the region, which an attacker does not have).
Status SkinInto(client::SkinClient& c, const std::string& mesh_id, const std::string& name) {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  request.mutable_output()->set_region(name);
  grpc::ClientContext context;
  auto reader = c.stub().Skin(&context, request);
  v1::SkinResponse part;
  while (reader->Read(&part)) {
  }
  return wire::FromGrpc(reader->Finish());
}

std::set<std::string> Names(client::SkinClient& c) {
  std::set<std::string> names;
  auto list = c.ListRegions();
  EXPECT_TRUE(list.ok()) << list.status().ToString();
  if (list.ok()) {
    for (const auto& r : list->regions()) names.insert(r.name());
  }
  return names;
}

// The owner skinning into its region the whole time, each answer decoded from the region
// and checked against the float64 reference.
class OwnerStream {
 public:
  OwnerStream(client::SkinClient& owner, const std::string& name, const SharedMemoryRegion& region)
      : mesh_arrays_(MakeSyntheticMesh({.vertex_count = kVertices, .influences = 4, .seed = 5})),
        mesh_(Mesh::Create(mesh_arrays_).value()) {
    auto info = owner.Upload(mesh_arrays_);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    if (!info.ok()) return;
    thread_ = std::thread([this, &owner, name, &region, id = info->mesh_id()] {
      const auto palette = [](uint64_t f) { return MakeSyntheticPalette(77, 1, f); };
      status_ = client::StreamFrames(
          owner,
          {.mesh_id = id,
           .backend = "sse",
           .output = {.name = name, .region = &region, .stride = Stride()},
           .frames = UINT64_MAX / 2,
           .window = 2,
           .stop = &stop_},
          palette, [&](client::FrameResult& r, std::chrono::nanoseconds) {
            Status s = r.status;
            if (s.ok()) s = client::DecodeRegionFrame(&r);
            if (s.ok() && !CompareWithReference(*mesh_, palette(r.frame), r.positions, {})
                               .within_tolerance()) {
              s = Internal(fmt::format("frame {} differs from the reference", r.frame));
            }
            if (s.ok()) {
              ++good_;
            } else if (bad_.fetch_add(1) == 0) {
              first_error_ = s.ToString();
            }
          });
    });
  }
  ~OwnerStream() { Stop(); }
  static uint64_t Stride() {
    return wire::RegionFrameBytes(kVertices, 1, VertexEncoding::kFloat32, false);
  }
  // Waits (60 s at most: "did not hang") until `more` frames beyond those so far were right.
  void WaitForMore(uint64_t more) {
    const uint64_t target = good_.load() + more;
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (good_.load() < target && bad_.load() == 0 &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(5ms);
    }
    EXPECT_GE(good_.load(), target) << "the owner's frames stopped coming";
  }
  void Stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  void ExpectEveryFrameRight() {
    Stop();
    EXPECT_TRUE(status_.ok()) << status_.ToString();
    EXPECT_EQ(bad_.load(), 0u) << first_error_;
    EXPECT_GT(good_.load(), 0u);
  }

 private:
  MeshArrays mesh_arrays_;
  std::shared_ptr<const Mesh> mesh_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> good_{0}, bad_{0};
  std::string first_error_;
  Status status_;
};

// What skinserve_region_peer said for each step: "STEP CODE message".
struct PeerStep {
  std::string step, code, text;
};

std::vector<PeerStep> RunPeer(const std::vector<std::string>& args) {
  std::string command = SKINSERVE_REGION_PEER;
  for (const std::string& a : args) command += " '" + a + "'";
  std::vector<PeerStep> steps;
  FILE* out = popen((command + " 2>&1").c_str(), "r");
  if (out == nullptr) {
    ADD_FAILURE() << "cannot run " << command;
    return steps;
  }
  char line[4096];
  while (std::fgets(line, sizeof(line), out) != nullptr) {
    std::istringstream in(line);
    PeerStep s;
    in >> s.step >> s.code;
    std::getline(in >> std::ws, s.text);
    steps.push_back(s);
  }
  EXPECT_EQ(pclose(out), 0) << command;
  return steps;
}

void ExpectStep(const PeerStep& s, const std::string& step, const std::string& code,
                const std::string& text = "") {
  EXPECT_EQ(s.step, step);
  EXPECT_EQ(s.code, code) << s.step << ": " << s.text;
  if (!text.empty()) {
    EXPECT_NE(s.text.find(text), std::string::npos) << s.step << ": " << s.text;
  }
}

// A file of `bytes` in the regions' folder, owned by `uid`; its key.
std::string MakeFile(const Folders& folders, const std::string& key, uint64_t bytes, uid_t uid) {
  const std::string path = folders.shm() + "/" + key;
  const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  EXPECT_GE(fd, 0) << path;
  EXPECT_EQ(ftruncate(fd, static_cast<off_t>(bytes)), 0);
  EXPECT_EQ(fchown(fd, uid, uid), 0);
  close(fd);
  return key;
}

TEST(RegionOwnersTest, OnTheUnixSocketAnotherUidOrProcessCanNeitherSeeNorUseNorTakeARegion) {
  Folders folders;
  auto server = StartShmServer(folders, QuickServerOptions());
  ASSERT_NE(server, nullptr);
  client::SkinClient owner(client::MakeChannel(folders.unix_target()));
  auto mine = MakeRegion(folders, "mine", 2 * OwnerStream::Stride());
  auto canary = MakeRegion(folders, "canary", 1 << 20);  // room for any frame
  ASSERT_TRUE(owner.RegisterRegion("mine", *mine).ok());
  ASSERT_TRUE(owner.RegisterRegion("canary", *canary).ok());
  OwnerStream stream(owner, "mine", *mine);
  stream.WaitForMore(3);

  // Another uid: lists nothing of the owner's, names its regions in vain, unregisters
  // nothing, and maps neither the owner's registered file nor a free one of the owner's uid.
  const std::string free_root_file = MakeFile(folders, "root-free", 4096, 0);
  const std::vector<std::string> as_other = {"--as-uid", std::to_string(kOtherUid),
                                             "--target", folders.unix_target(),
                                             "--dir",    folders.shm()};
  auto steps = RunPeer([&] {
    auto a = as_other;
    for (const char* s : {"list", "skin", "canary", "skin", "mine", "unregister", "mine",
                          "unregister", "canary", "register", "theirs"}) {
      a.push_back(s);
    }
    a.insert(a.end(), {mine->key(), "4096", "register", "free", free_root_file, "4096", "make",
                       "own", "4096", "list"});
    return a;
  }());
  ASSERT_EQ(steps.size(), 9u);
  ExpectStep(steps[0], "list", "OK");
  EXPECT_EQ(steps[0].text, "") << "another uid lists the owner's regions";
  ExpectStep(steps[1], "skin", "FAILED_PRECONDITION", "'canary'");
  ExpectStep(steps[2], "skin", "FAILED_PRECONDITION", "'mine'");
  ExpectStep(steps[3], "unregister", "NOT_FOUND", "'mine'");
  ExpectStep(steps[4], "unregister", "NOT_FOUND", "'canary'");
  ExpectStep(steps[5], "register", "PERMISSION_DENIED", "owned by uid 0, not by uid 65534");
  ExpectStep(steps[6], "register", "PERMISSION_DENIED", "owned by uid 0, not by uid 65534");
  ExpectStep(steps[7], "make", "OK");  // its own file: fine
  ExpectStep(steps[8], "list", "OK", "own");
  EXPECT_EQ(steps[8].text, "own");
  const std::string others_key = steps[7].text;

  // Another process of that same uid is another peer: the first one's region is not its
  // own, and the first one's file is registered already.
  steps = RunPeer([&] {
    auto a = as_other;
    a.insert(a.end(), {"list", "register", "again", others_key, "4096", "unregister", "own", "skin",
                       "own", "make", "second", "4096", "list"});
    return a;
  }());
  ASSERT_EQ(steps.size(), 6u);
  ExpectStep(steps[0], "list", "OK");
  EXPECT_EQ(steps[0].text, "");
  ExpectStep(steps[1], "register", "ALREADY_EXISTS", "registered already");
  ExpectStep(steps[2], "unregister", "NOT_FOUND", "'own'");
  ExpectStep(steps[3], "skin", "FAILED_PRECONDITION", "'own'");
  ExpectStep(steps[4], "make", "OK");
  ExpectStep(steps[5], "list", "OK");
  EXPECT_EQ(steps[5].text, "second");

  // The owner (root) maps its own files once, and no file of another uid.
  Status again = owner.RegisterRegion("mine-again", *mine).status();
  EXPECT_EQ(again.code(), StatusCode::kAlreadyExists) << again.ToString();
  Status theirs = Register(owner, "theirs", others_key, 4096);
  EXPECT_EQ(theirs.code(), StatusCode::kPermissionDenied) << theirs.ToString();
  EXPECT_NE(theirs.message().find("owned by uid 65534, not by uid 0"), std::string::npos)
      << theirs.ToString();
  EXPECT_EQ(Names(owner), (std::set<std::string>{"canary", "mine"}));
  EXPECT_EQ(owner.GetServerStats()->regions(), 4u) << "the peers' regions exist, unseen";

  // Meanwhile the owner's frames went on, each one right; nobody wrote into the canary.
  stream.WaitForMore(5);
  stream.ExpectEveryFrameRight();
  EXPECT_TRUE(AllCanary(*canary)) << "another peer's frame was written into the owner's region";
  EXPECT_TRUE(owner.UnregisterRegion("mine").ok());
  EXPECT_TRUE(owner.UnregisterRegion("canary").ok());
}

// The frame socket (--frame-socket) knows its peers as the Unix listener does: a frame sent
// there names only regions its own process registered over gRPC; another uid's or another
// process's frames into the owner's region are refused, and their own regions serve them.
TEST(RegionOwnersTest, OnTheFrameSocketAFrameNamesOnlyItsOwnProcesssRegions) {
  Folders folders;
  server::ServerOptions options = QuickServerOptions();
  options.frame_socket = folders.frame_socket();
  auto server = StartShmServer(folders, options);
  ASSERT_NE(server, nullptr);
  chmod(folders.frame_socket().c_str(), 0666);
  client::SkinClient owner(client::MakeChannel(folders.unix_target()));
  auto mine = MakeRegion(folders, "mine", 2 * OwnerStream::Stride());
  ASSERT_TRUE(owner.RegisterRegion("mine", *mine).ok());
  for (const bool other_uid : {true, false}) {
    std::vector<std::string> args = {"--target",    folders.unix_target(), "--dir",
                                     folders.shm(), "--frame-socket",      folders.frame_socket()};
    if (other_uid) args.insert(args.begin(), {"--as-uid", std::to_string(kOtherUid)});
    args.insert(args.end(), {"socket-skin", "mine", "make", "own", "1048576", "socket-skin", "own",
                             "skin", "own"});
    const auto steps = RunPeer(args);
    const std::string who = other_uid ? "another uid" : "another process of the owner's uid";
    ASSERT_EQ(steps.size(), 4u) << who;
    ExpectStep(steps[0], "socket-skin", "FAILED_PRECONDITION", "'mine'");
    ExpectStep(steps[1], "make", "OK");
    ExpectStep(steps[2], "socket-skin", "OK");  // its own region, registered over gRPC
    ExpectStep(steps[3], "skin", "OK");
  }
  EXPECT_TRUE(AllCanary(*mine)) << "another peer's frame was written into the owner's region";
}

TEST(RegionOwnersTest, OverPlainTcpEveryRegionCallIsRefusedAlikeAndFramesStillServe) {
  Folders folders;
  auto server = StartShmServer(folders, QuickServerOptions());
  ASSERT_NE(server, nullptr);
  client::SkinClient owner(client::MakeChannel(folders.unix_target()));
  auto mine = MakeRegion(folders, "mine", 2 * OwnerStream::Stride());
  ASSERT_TRUE(owner.RegisterRegion("mine", *mine).ok());
  OwnerStream stream(owner, "mine", *mine);
  stream.WaitForMore(3);

  client::SkinClient tcp(client::MakeChannel(TcpTarget(*server)));
  const std::string small = MakeFile(folders, "small", 4096, 0);
  auto mesh = tcp.Upload(MakeSyntheticMesh({.vertex_count = 500, .influences = 2}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const std::vector<Status> answers = {
      tcp.ListRegions().status(),
      Register(tcp, "theirs", mine->key(), 4096),
      Register(tcp, "r", "missing", 4096),
      Register(tcp, "r", small, 1 << 20),
      Register(tcp, "r", small, 4096),
      tcp.UnregisterRegion("mine"),
      SkinInto(tcp, mesh->mesh_id(), "mine"),
  };
  for (const Status& s : answers) {
    EXPECT_EQ(s.code(), StatusCode::kPermissionDenied) << s.ToString();
    EXPECT_EQ(s.message(), answers[0].message()) << "one answer for every region call";
  }
  const std::string& message = answers[0].message();
  EXPECT_NE(message.find("--shm-over-tcp"), std::string::npos) << message;
  EXPECT_NE(message.find("Unix socket"), std::string::npos) << message;
  EXPECT_EQ(message.find(folders.shm()), std::string::npos) << message;
  // Frames over TCP (into gRPC, not a region) are served as before.
  Status s = UploadSkinAndStream(tcp);
  EXPECT_TRUE(s.ok()) << s.ToString();

  stream.WaitForMore(5);
  stream.ExpectEveryFrameRight();
  EXPECT_EQ(Names(owner), (std::set<std::string>{"mine"}));
}

TEST(RegionOwnersTest, ShmOverTcpWithoutMutualTlsIsAStartUpErrorNamingBothOptions) {
  server::ServerOptions options = QuickServerOptions();
  options.shm_over_tcp = true;
  options.listen = {"127.0.0.1:0"};
  for (bool tls : {false, true}) {
    if (tls) UseServerTls(&options, "a", /*mutual=*/false);
    auto started = server::SkinServer::Start(options);
    ASSERT_FALSE(started.ok()) << (tls ? "TLS" : "plaintext");
    EXPECT_NE(started.status().message().find("--shm-over-tcp"), std::string::npos);
    EXPECT_NE(started.status().message().find("--tls-client-ca"), std::string::npos);
  }
}

// What a TCP registration said, with the key it named taken out.
std::string WithoutKey(const Status& s, const std::string& key) {
  std::string text = fmt::format("{} {}", StatusCodeName(s.code()), s.message());
  for (std::size_t at = text.find(key); at != std::string::npos; at = text.find(key)) {
    text.replace(at, key.size(), "KEY");
  }
  return text;
}

TEST(RegionOwnersTest, OverMutualTlsACertificateOwnsItsRegionsAndNoErrorTellsAboutFiles) {
  Folders folders;
  server::ServerOptions options = QuickServerOptions();
  UseServerTls(&options, "a", /*mutual=*/true);
  options.shm_over_tcp = true;
  auto server = StartShmServer(folders, options);
  ASSERT_NE(server, nullptr);
  client::SkinClient renderer(client::MakeChannel(TcpTarget(*server), ClientTls("a", "renderer")));
  client::SkinClient guest(client::MakeChannel(TcpTarget(*server), ClientTls("a", "guest")));
  auto mine = MakeRegion(folders, "mine", 2 * OwnerStream::Stride());
  auto canary = MakeRegion(folders, "canary", 1 << 20);
  ASSERT_TRUE(renderer.RegisterRegion("mine", *mine).ok());
  ASSERT_TRUE(renderer.RegisterRegion("canary", *canary).ok());
  OwnerStream stream(renderer, "mine", *mine);
  stream.WaitForMore(3);

  // Another certificate: nothing listed, named, unregistered.
  EXPECT_EQ(Names(guest), std::set<std::string>{});
  auto mesh = guest.Upload(MakeSyntheticMesh({.vertex_count = 500, .influences = 2}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  for (const char* name : {"canary", "mine"}) {
    Status s = SkinInto(guest, mesh->mesh_id(), name);
    EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
    s = guest.UnregisterRegion(name);
    EXPECT_EQ(s.code(), StatusCode::kNotFound) << s.ToString();
  }
  // Registered already, missing, too small, another uid's, a folder, a link, a FIFO: one
  // answer, which says nothing about the file.
  const std::string small = MakeFile(folders, "small", 4096, 0);
  const std::string nobodys = MakeFile(folders, "nobodys", 1 << 20, kOtherUid);
  ASSERT_EQ(mkdir((folders.shm() + "/folder").c_str(), 0700), 0);
  ASSERT_EQ(symlink(mine->path().c_str(), (folders.shm() + "/link").c_str()), 0);
  ASSERT_EQ(mkfifo((folders.shm() + "/fifo").c_str(), 0600), 0);
  const std::string expected = WithoutKey(Register(guest, "r", mine->key(), 4096), mine->key());
  EXPECT_NE(expected.find("INVALID_ARGUMENT"), std::string::npos) << expected;
  EXPECT_EQ(expected.find(folders.shm()), std::string::npos) << expected;
  for (const auto& [key, bytes] : std::vector<std::pair<std::string, uint64_t>>{{"missing", 4096},
                                                                                {small, 8192},
                                                                                {nobodys, 4096},
                                                                                {"folder", 4096},
                                                                                {"link", 4096},
                                                                                {"fifo", 4096}}) {
    EXPECT_EQ(WithoutKey(Register(guest, "r", key, bytes), key), expected) << key;
  }
  // Its own registration works, and is its own.
  EXPECT_TRUE(Register(guest, "r", small, 4096).ok());
  EXPECT_EQ(Names(guest), std::set<std::string>{"r"});
  EXPECT_EQ(Names(renderer), (std::set<std::string>{"canary", "mine"}));

  stream.WaitForMore(5);
  stream.ExpectEveryFrameRight();
  EXPECT_TRUE(AllCanary(*canary)) << "another certificate's frame was written into the region";
}

TEST(RegionOwnersTest, AFileUnderALeaseIsRefusedAtOnceAndRegisteredOnceTheLeaseIsGone) {
  Folders folders;
  auto server = StartShmServer(folders, QuickServerOptions());
  ASSERT_NE(server, nullptr);
  client::SkinClient owner(client::MakeChannel(folders.unix_target()));
  const std::string leased = MakeFile(folders, "leased", 4096, 0);
  // A read lease: an open for writing must wait for its holder (up to the kernel's
  // lease-break-time, 45 s by default) unless it is non-blocking. The holder is told by
  // SIGIO, whose default action would end this test.
  signal(SIGIO, SIG_IGN);
  const int fd = open((folders.shm() + "/" + leased).c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(fcntl(fd, F_SETLEASE, F_RDLCK), 0) << std::strerror(errno);
  const auto start = std::chrono::steady_clock::now();
  Status s = Register(owner, "leased", leased, 4096);
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
  EXPECT_NE(s.message().find("lease"), std::string::npos) << s.ToString();
  EXPECT_LT(took, 20s) << "the open waited for the lease";
  ASSERT_EQ(fcntl(fd, F_SETLEASE, F_UNLCK), 0);
  close(fd);
  EXPECT_TRUE(Register(owner, "leased", leased, 4096).ok());
}

}  // namespace
}  // namespace skinserve::testing
