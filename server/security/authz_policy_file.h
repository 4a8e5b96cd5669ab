// PolicyFile: the --authz-policy file, read at start (a policy that does not parse is a
// start-up error) and re-read on a timer, so a mounted ConfigMap's edit takes effect
// without a restart. An edit that does not parse is logged and the last good policy stays
// in force, as gRPC's own file watcher does. Each call is checked once, when it starts: a
// stream opened before an edit is not cut by it.
#pragma once

#include <grpcpp/server_context.h>

#include <chrono>
#include <memory>
#include <mutex>
#include <string>

#include "security/authz_policy.h"
#include "threads/periodic_thread.h"

namespace skinserve::server {

class PolicyFile {
 public:
  static Result<std::unique_ptr<PolicyFile>> Load(const std::string& path,
                                                  std::chrono::milliseconds refresh);
  ~PolicyFile();

  // OK, or PERMISSION_DENIED naming the method, the caller and the policy.
  Status Check(const grpc::ServerContextBase& context, std::string_view path) const;
  // The same for `peer` (a frame-socket connection's: unauthenticated, like any Unix peer).
  Status Check(const Peer& peer, std::string_view path) const;
  std::shared_ptr<const AuthorizationPolicy> current() const;

 private:
  explicit PolicyFile(std::string path) : path_(std::move(path)) {}
  // The watcher's round: Reload, logging a file that no longer parses.
  void ReloadOrLog();
  // Reads and parses the file; true when it changed and parsed (then it is in force).
  Result<bool> Reload();

  const std::string path_;
  mutable std::mutex mutex_;
  std::shared_ptr<const AuthorizationPolicy> policy_;
  std::string text_;  // the file as last read (parsed or not), to notice changes
  std::unique_ptr<PeriodicThread> watcher_;  // last, so it stops first; once the file loaded
};

// What every service calls first in each method: OK when `policy` is null (no
// --authz-policy) or allows "/`service`/`method`" ("skinserve.v1.GpuRegions",
// "RegisterGpuRegion") for this call's peer; else PolicyFile::Check's PERMISSION_DENIED.
Status Authorize(const PolicyFile* policy, const grpc::ServerContextBase& context,
                 std::string_view service, std::string_view method);

}  // namespace skinserve::server
