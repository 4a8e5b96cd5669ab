// RegionOwner: who registers, names, lists and unregisters shared-memory regions. A region
// belongs to the peer that registered it, and only that peer sees it
// (docs/serving/shared-memory.md#ownership):
//   - on a Unix socket, the client's process as the kernel reports it (SO_PEERCRED: its
//     uid and pid, with the process's start time so that a reused pid is someone else);
//     it may map files its uid owns;
//   - over TCP, only when the operator allows it (--shm-over-tcp, which needs mutual TLS),
//     the identity of the client's verified certificate; it may map files the server's
//     own uid owns (the server cannot learn a TCP client's uid), and errors about files
//     say nothing about them (whether one exists, its size, its owner).
// Any other caller gets PERMISSION_DENIED saying what is needed.
#pragma once

#include <grpcpp/server_context.h>
#include <sys/types.h>

#include <string>

#include "security/unix_peers.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

struct RegionOwner {
  // The identity regions are kept under, also what logs show: "uid 1000 pid 4242" (with
  // the start time when known) or "certificate spiffe://renderers/7".
  std::string id;
  uid_t file_uid = 0;   // the files it may map are owned by this uid
  bool remote = false;  // over TCP: errors about files say nothing about them

  static RegionOwner OfUnixPeer(const UnixPeerCredentials& peer);
};

// How the server tells who may use regions: the Unix peers it accepted itself, and
// whether the operator allows region RPCs over (mutual-TLS) TCP.
struct RegionAccessPolicy {
  const UnixPeers* unix_peers = nullptr;
  bool over_tcp = false;  // --shm-over-tcp
};

// The owner the call's peer is, or PERMISSION_DENIED naming what it lacks.
Result<RegionOwner> RegionOwnerOf(const grpc::ServerContextBase& context,
                                  const RegionAccessPolicy& policy);

}  // namespace skinserve::server
