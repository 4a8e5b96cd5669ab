// skinserve_region_peer: a second client process for the region ownership tests, run as
// another uid (--as-uid: it drops root before it connects) or as another process of the
// same uid. It does what its arguments say over one channel, in order, and prints one line
// per step: "STEP CODE message" (CODE as StatusCodeName, OK when it worked).
//   list                    the names ListRegions shows it, comma-separated
//   register NAME KEY BYTES RegisterRegion of an existing file
//   make NAME BYTES         creates a file of its own in --dir (left there), registers it;
//                           prints its key
//   skin NAME               uploads a small mesh (once) and skins a frame into region NAME
//   socket-skin NAME        the same frame sent over the server's frame socket (--frame-socket)
//   unregister NAME         UnregisterRegion
#include <fcntl.h>
#include <fmt/format.h>
#include <grp.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "skinserve/client/channel.h"
#include "skinserve/client/frame_socket_client.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"

namespace {

using namespace skinserve;

void Say(const std::string& step, const Status& status, const std::string& detail = "") {
  std::printf("%s %s %s\n", step.c_str(), StatusCodeName(status.code()),
              status.ok() ? detail.c_str() : status.message().c_str());
  std::fflush(stdout);
}

Status SkinInto(client::SkinClient& c, const std::string& mesh_id, const std::string& region) {
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  request.mutable_output()->set_region(region);
  grpc::ClientContext context;
  auto reader = c.stub().Skin(&context, request);
  v1::SkinResponse part;
  while (reader->Read(&part)) {
  }
  return wire::FromGrpc(reader->Finish());
}

// SkinInto's frame over the frame socket at `path`: the answer's status (the frame's own
// error, or the connection's end).
Status SocketSkinInto(const std::string& path, const std::string& mesh_id,
                      const std::string& region) {
  auto socket = client::FrameSocketClient::Connect(path);
  if (!socket.ok()) return socket.status();
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  const auto palette = MakeSyntheticPalette(77, 1, 0);
  request.set_palette(palette.data(), palette.size() * sizeof(float));
  request.mutable_output()->set_region(region);
  if (!(*socket)->Write(request)) return (*socket)->Finish();
  grpc::ByteBuffer part;
  if (!(*socket)->Read(&part)) return (*socket)->Finish();
  v1::SkinResponse response;
  std::vector<grpc::Slice> slices;
  (void)part.Dump(&slices);
  std::string bytes;
  for (const auto& slice : slices)
    bytes.append(reinterpret_cast<const char*>(slice.begin()), slice.size());
  if (!response.ParseFromString(bytes)) return Internal("the answer is not a SkinResponse");
  if (!response.has_error()) return Status::Ok();
  return wire::FromGrpc(grpc::Status(static_cast<grpc::StatusCode>(response.error().code()),
                                     response.error().message()));
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

// A file of this process's uid in `dir`: "peer-PID-NAME", `bytes` long.
Result<std::string> MakeFile(const std::string& dir, const std::string& name, uint64_t bytes) {
  const std::string key = fmt::format("peer-{}-{}", getpid(), name);
  const int fd = open((dir + "/" + key).c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return Internal(fmt::format("cannot create {}/{}", dir, key));
  const bool sized = ftruncate(fd, static_cast<off_t>(bytes)) == 0;
  close(fd);
  if (!sized) return Internal(fmt::format("cannot size {}/{}", dir, key));
  return key;
}

int Run(const std::vector<std::string>& args) {
  std::string target, dir, frame_socket;
  std::size_t i = 0;
  for (; i + 1 < args.size() && args[i].starts_with("--"); i += 2) {
    if (args[i] == "--target") {
      target = args[i + 1];
    } else if (args[i] == "--dir") {
      dir = args[i + 1];
    } else if (args[i] == "--frame-socket") {
      frame_socket = args[i + 1];
    } else if (args[i] == "--as-uid") {
      const uid_t uid = static_cast<uid_t>(std::stoul(args[i + 1]));
      if (setgroups(0, nullptr) != 0 || setgid(uid) != 0 || setuid(uid) != 0) {
        std::perror("dropping to --as-uid");
        return 2;
      }
    } else {
      std::fprintf(stderr, "unknown option %s\n", args[i].c_str());
      return 2;
    }
  }
  client::SkinClient c(client::MakeChannel(target));
  std::string mesh_id;
  for (; i < args.size(); ++i) {
    const std::string& step = args[i];
    const auto arg = [&](std::size_t k) { return i + k < args.size() ? args[i + k] : ""; };
    if (step == "list") {
      auto list = c.ListRegions();
      std::string names;
      if (list.ok()) {
        for (const auto& r : list->regions()) names += (names.empty() ? "" : ",") + r.name();
      }
      Say(step, list.status(), names);
    } else if (step == "register") {
      Say(step, Register(c, arg(1), arg(2), std::stoull(arg(3))));
      i += 3;
    } else if (step == "make") {
      Result<std::string> key = MakeFile(dir, arg(1), std::stoull(arg(2)));
      Say(step, key.ok() ? Register(c, arg(1), *key, std::stoull(arg(2))) : key.status(),
          key.ok() ? *key : "");
      i += 2;
    } else if (step == "skin" || step == "socket-skin") {
      if (mesh_id.empty()) {
        auto info = c.Upload(MakeSyntheticMesh({.vertex_count = 500, .influences = 2}));
        if (!info.ok()) {
          Say(step, info.status());
          return 1;
        }
        mesh_id = info->mesh_id();
      }
      Say(step, step == "skin" ? SkinInto(c, mesh_id, arg(1))
                               : SocketSkinInto(frame_socket, mesh_id, arg(1)));
      i += 1;
    } else if (step == "unregister") {
      Say(step, c.UnregisterRegion(arg(1)));
      i += 1;
    } else {
      std::fprintf(stderr, "unknown step %s\n", step.c_str());
      return 2;
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return Run(std::vector<std::string>(argv + 1, argv + argc)); }
