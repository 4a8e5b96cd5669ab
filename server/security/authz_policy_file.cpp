#include "security/authz_policy_file.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <sstream>

namespace skinserve::server {

Result<std::unique_ptr<PolicyFile>> PolicyFile::Load(const std::string& path,
                                                     std::chrono::milliseconds refresh) {
  std::unique_ptr<PolicyFile> file(new PolicyFile(path));
  auto loaded = file->Reload();
  if (!loaded.ok()) return loaded.status();
  file->watcher_ =
      std::make_unique<PeriodicThread>(refresh, [f = file.get()] { f->ReloadOrLog(); });
  return file;
}

PolicyFile::~PolicyFile() = default;

Result<bool> PolicyFile::Reload() {
  std::ifstream in(path_);
  if (!in) return InvalidArgument(fmt::format("--authz-policy '{}': cannot read the file", path_));
  std::stringstream text;
  text << in.rdbuf();
  {
    std::lock_guard lock(mutex_);
    if (policy_ != nullptr && text.str() == text_) return false;
    text_ = text.str();
  }
  auto policy = AuthorizationPolicy::Parse(text.str());
  if (!policy.ok()) {
    return InvalidArgument(
        fmt::format("--authz-policy '{}': {}", path_, policy.status().message()));
  }
  auto parsed = std::make_shared<const AuthorizationPolicy>(std::move(policy).value());
  spdlog::info("--authz-policy '{}': policy '{}' in force ({} allow rules, {} deny rules)", path_,
               parsed->name(), parsed->allow_rules(), parsed->deny_rules());
  std::lock_guard lock(mutex_);
  policy_ = std::move(parsed);
  return true;
}

void PolicyFile::ReloadOrLog() {
  if (auto reloaded = Reload(); !reloaded.ok()) {
    spdlog::error("{}; the last good policy stays in force", reloaded.status().message());
  }
}

std::shared_ptr<const AuthorizationPolicy> PolicyFile::current() const {
  std::lock_guard lock(mutex_);
  return policy_;
}

Status PolicyFile::Check(const grpc::ServerContextBase& context, std::string_view path) const {
  const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
  return Check(Peer::Of(auth.get()), path);
}

Status PolicyFile::Check(const Peer& peer, std::string_view path) const {
  const std::shared_ptr<const AuthorizationPolicy> policy = current();
  const AuthorizationPolicy::Decision decision = policy->Evaluate(peer, path);
  if (decision.allowed) return Status::Ok();
  return {StatusCode::kPermissionDenied,
          fmt::format("{} is not allowed for {} by the authorization policy '{}' ({}; "
                      "--authz-policy)",
                      path, peer.Describe(), policy->name(),
                      decision.rule.empty() ? "no allow rule matches"
                                            : "deny rule '" + decision.rule + "'")};
}

Status Authorize(const PolicyFile* policy, const grpc::ServerContextBase& context,
                 std::string_view service, std::string_view method) {
  if (policy == nullptr) return Status::Ok();
  return policy->Check(context, fmt::format("/{}/{}", service, method));
}

}  // namespace skinserve::server
