#include "shm/region_owner.h"

#include <fmt/format.h>
#include <unistd.h>

#include "security/authz_policy.h"

namespace skinserve::server {

RegionOwner RegionOwner::OfUnixPeer(const UnixPeerCredentials& peer) {
  RegionOwner owner;
  // A pid the server cannot see (another pid namespace) leaves the uid alone as the owner:
  // every such process of that uid is one peer (docs/serving/shared-memory.md#ownership).
  owner.id = peer.pid == 0
                 ? fmt::format("uid {} (pid not visible)", peer.uid)
                 : fmt::format("uid {} pid {} started {}", peer.uid, peer.pid, peer.start_ticks);
  owner.file_uid = peer.uid;
  return owner;
}

Result<RegionOwner> RegionOwnerOf(const grpc::ServerContextBase& context,
                                  const RegionAccessPolicy& policy) {
  const std::string peer = context.peer();
  if (policy.unix_peers != nullptr) {
    if (auto unix_peer = policy.unix_peers->Find(peer)) return RegionOwner::OfUnixPeer(*unix_peer);
  }
  if (peer.starts_with("unix:") || peer.starts_with("fd:")) {
    // Not one of the connections the server accepted itself: no credentials to go by.
    return PermissionDenied(
        "shared-memory regions: this Unix-socket connection's credentials are unknown to the "
        "server");
  }
  if (!policy.over_tcp) {
    return PermissionDenied(
        "shared-memory regions are not served over TCP on this server: connect to its Unix "
        "socket (--listen unix:PATH), or have the operator allow them over mutual TLS "
        "(--shm-over-tcp)");
  }
  const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
  const Peer tls = Peer::Of(auth.get());
  // The principal as the authorization policy reads it: URI SAN, else DNS SAN, else subject.
  const std::string identity = !tls.uri_sans.empty()   ? tls.uri_sans[0]
                               : !tls.dns_sans.empty() ? tls.dns_sans[0]
                                                       : tls.subject;
  if (!tls.authenticated || identity.empty()) {
    return PermissionDenied(
        "shared-memory regions over TCP need a client certificate (mutual TLS): its identity "
        "owns the regions");
  }
  return RegionOwner{.id = "certificate " + identity, .file_uid = geteuid(), .remote = true};
}

}  // namespace skinserve::server
