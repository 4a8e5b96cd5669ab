// AuthorizationPolicy: gRPC's authorization policy format (the JSON of gRPC's
// FileWatcherAuthorizationPolicyProvider: allow_rules and deny_rules, each naming methods
// by path and clients by certificate principal), read and evaluated here. gRPC 1.51 as
// Debian 12 ships it has the authorization engine but not the policy provider (the
// FileWatcherAuthorizationPolicyProvider and grpc_authorization_policy_provider_* symbols
// are in no installed library), so skinserve reads the same format and checks it at the
// start of every call of its service, with gRPC's rules:
//   - a call matching any deny rule is denied; else one matching any allow rule is
//     allowed; else it is denied;
//   - a rule matches when its source and its request do (a missing one matches all);
//   - principals match authenticated peers only (TLS with a client certificate): against
//     the certificate's URI SANs, then its DNS SANs, then its subject;
//   - a pattern is exact, "prefix*", "*suffix", or "*" (anything not empty).
// Request headers are not supported (a policy naming them is refused, not half-applied).
// Unlike gRPC's reader, a path that can match no method the server serves (MethodCatalog:
// every service of skinning.proto, and gRPC's health and reflection) is refused at load.
#pragma once

#include <grpcpp/security/auth_context.h>

#include <string>
#include <string_view>
#include <vector>

#include "security/method_catalog.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

// Who is calling, as the policy sees it: the transport's identity of the peer.
struct Peer {
  bool authenticated = false;  // TLS (a client without a certificate matches no principal)
  std::vector<std::string> uri_sans, dns_sans;
  std::string subject;  // RFC 2253, e.g. "CN=operator,O=skinserve"

  static Peer Of(const grpc::AuthContext* context);  // null: plaintext
  // The first URI SAN, DNS SAN or subject, or "an unauthenticated client", for messages.
  std::string Describe() const;
};

class AuthorizationPolicy {
 public:
  // Errors name the rule and the field ("allow_rules[1].source.principals[0]: ..."); a
  // path that matches none of `methods` is one.
  static Result<AuthorizationPolicy> Parse(std::string_view json,
                                           const MethodCatalog& methods = MethodCatalog::Served());

  struct Decision {
    bool allowed = false;
    std::string rule;  // the rule that decided; empty when no rule matched (denied)
  };
  Decision Evaluate(const Peer& peer, std::string_view path) const;

  const std::string& name() const { return name_; }
  std::size_t allow_rules() const { return allow_.size(); }
  std::size_t deny_rules() const { return deny_.size(); }

 private:
  struct Pattern {
    enum class Kind { kExact, kPrefix, kSuffix, kAny } kind;
    std::string text;
    bool Matches(std::string_view value) const;
  };
  struct Rule {
    std::string name;
    std::vector<Pattern> principals;  // empty: any peer
    std::vector<Pattern> paths;       // empty: any method
    bool Matches(const Peer& peer, std::string_view path) const;
  };
  static Result<Rule> ParseRule(const void* json, const std::string& where);
  // OK when each of `paths` (those of rule `where`) matches a method of `methods`.
  static Status CheckPaths(const std::vector<Pattern>& paths, const MethodCatalog& methods,
                           const std::string& where);

  std::string name_;
  std::vector<Rule> allow_, deny_;
};

}  // namespace skinserve::server
