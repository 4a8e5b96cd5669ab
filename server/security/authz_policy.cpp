#include "security/authz_policy.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <grpc/grpc_security_constants.h>

#include <algorithm>
#include <nlohmann/json.hpp>

namespace skinserve::server {
namespace {

using Json = nlohmann::json;

std::vector<std::string> Values(const grpc::AuthContext& context, const char* property) {
  std::vector<std::string> out;
  for (const grpc::string_ref& value : context.FindPropertyValues(property)) {
    out.emplace_back(value.data(), value.size());
  }
  return out;
}

Status Unknown(const Json& object, const std::string& where,
               std::initializer_list<std::string_view> known) {
  for (const auto& [key, value] : object.items()) {
    if (std::find(known.begin(), known.end(), key) == known.end()) {
      return InvalidArgument(
          fmt::format("{}: unknown field \"{}\" (known: {})", where, key, fmt::join(known, ", ")));
    }
  }
  return Status::Ok();
}

}  // namespace

Peer Peer::Of(const grpc::AuthContext* context) {
  Peer peer;
  if (context == nullptr) return peer;
  const std::vector<std::string> type =
      Values(*context, GRPC_TRANSPORT_SECURITY_TYPE_PROPERTY_NAME);
  peer.authenticated = !type.empty() && (type[0] == GRPC_SSL_TRANSPORT_SECURITY_TYPE ||
                                         type[0] == GRPC_TLS_TRANSPORT_SECURITY_TYPE);
  if (!peer.authenticated) return peer;
  peer.uri_sans = Values(*context, GRPC_PEER_URI_PROPERTY_NAME);
  peer.dns_sans = Values(*context, GRPC_PEER_DNS_PROPERTY_NAME);
  const std::vector<std::string> subject = Values(*context, GRPC_X509_SUBJECT_PROPERTY_NAME);
  if (!subject.empty()) peer.subject = subject[0];
  return peer;
}

std::string Peer::Describe() const {
  if (!uri_sans.empty()) return uri_sans[0];
  if (!dns_sans.empty()) return dns_sans[0];
  if (!subject.empty()) return subject;
  return authenticated ? "a TLS client without a certificate" : "an unauthenticated client";
}

bool AuthorizationPolicy::Pattern::Matches(std::string_view value) const {
  switch (kind) {
    case Kind::kExact:
      return value == text;
    case Kind::kPrefix:
      return value.starts_with(text);
    case Kind::kSuffix:
      return value.ends_with(text);
    case Kind::kAny:
      return !value.empty();
  }
  return false;
}

bool AuthorizationPolicy::Rule::Matches(const Peer& peer, std::string_view path) const {
  if (!paths.empty() &&
      std::none_of(paths.begin(), paths.end(), [&](const Pattern& p) { return p.Matches(path); })) {
    return false;
  }
  if (principals.empty()) return true;
  if (!peer.authenticated) return false;
  for (const Pattern& p : principals) {
    const auto any = [&](const std::vector<std::string>& names) {
      return std::any_of(names.begin(), names.end(),
                         [&](const std::string& n) { return p.Matches(n); });
    };
    if (any(peer.uri_sans) || any(peer.dns_sans) || p.Matches(peer.subject)) return true;
  }
  return false;
}

Result<AuthorizationPolicy::Rule> AuthorizationPolicy::ParseRule(const void* json_rule,
                                                                 const std::string& where) {
  const Json& json = *static_cast<const Json*>(json_rule);
  if (!json.is_object()) return InvalidArgument(fmt::format("{}: not an object", where));
  if (Status s = Unknown(json, where, {"name", "source", "request"}); !s.ok()) return s;
  Rule rule;
  if (!json.contains("name") || !json["name"].is_string() ||
      json["name"].get<std::string>().empty()) {
    return InvalidArgument(fmt::format("{}: \"name\" is missing or not a string", where));
  }
  rule.name = json["name"].get<std::string>();
  const auto patterns = [&](const Json& parent, const char* object, const char* field,
                            std::vector<Pattern>* out) -> Status {
    const std::string at = fmt::format("{}.{}.{}", where, object, field);
    if (!parent.contains(field)) return Status::Ok();
    const Json& list = parent[field];
    if (!list.is_array()) return InvalidArgument(fmt::format("{}: not a list", at));
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (!list[i].is_string()) {
        return InvalidArgument(fmt::format("{}[{}]: not a string", at, i));
      }
      const std::string text = list[i].get<std::string>();
      if (text == "*") {
        out->push_back({Pattern::Kind::kAny, ""});
      } else if (text.starts_with('*')) {
        out->push_back({Pattern::Kind::kSuffix, text.substr(1)});
      } else if (text.ends_with('*')) {
        out->push_back({Pattern::Kind::kPrefix, text.substr(0, text.size() - 1)});
      } else {
        out->push_back({Pattern::Kind::kExact, text});
      }
    }
    return Status::Ok();
  };
  if (json.contains("source")) {
    const Json& source = json["source"];
    const std::string at = where + ".source";
    if (!source.is_object()) return InvalidArgument(fmt::format("{}: not an object", at));
    if (Status s = Unknown(source, at, {"principals"}); !s.ok()) return s;
    if (Status s = patterns(source, "source", "principals", &rule.principals); !s.ok()) return s;
  }
  if (json.contains("request")) {
    const Json& request = json["request"];
    const std::string at = where + ".request";
    if (!request.is_object()) return InvalidArgument(fmt::format("{}: not an object", at));
    if (request.contains("headers")) {
      return InvalidArgument(fmt::format(
          "{}.headers: request headers are not supported by skinserve's policy reader (it "
          "takes principals and paths)",
          at));
    }
    if (Status s = Unknown(request, at, {"paths"}); !s.ok()) return s;
    if (Status s = patterns(request, "request", "paths", &rule.paths); !s.ok()) return s;
  }
  return rule;
}

Status AuthorizationPolicy::CheckPaths(const std::vector<Pattern>& paths,
                                       const MethodCatalog& methods, const std::string& where) {
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const Pattern& p = paths[i];
    if (std::any_of(methods.paths().begin(), methods.paths().end(),
                    [&](const std::string& path) { return p.Matches(path); })) {
      continue;
    }
    const std::string written = p.kind == Pattern::Kind::kPrefix   ? p.text + "*"
                                : p.kind == Pattern::Kind::kSuffix ? "*" + p.text
                                                                   : p.text;
    return InvalidArgument(
        fmt::format("{}.request.paths[{}]: \"{}\" matches no method this server serves ({})", where,
                    i, written, methods.Known(p.kind == Pattern::Kind::kSuffix ? "" : p.text)));
  }
  return Status::Ok();
}

Result<AuthorizationPolicy> AuthorizationPolicy::Parse(std::string_view text,
                                                       const MethodCatalog& methods) {
  const Json json = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) return InvalidArgument("not valid JSON");
  if (!json.is_object()) return InvalidArgument("not a JSON object");
  if (Status s = Unknown(json, "policy", {"name", "allow_rules", "deny_rules"}); !s.ok()) {
    return s;
  }
  AuthorizationPolicy policy;
  if (!json.contains("name") || !json["name"].is_string()) {
    return InvalidArgument("policy: \"name\" is missing or not a string");
  }
  policy.name_ = json["name"].get<std::string>();
  if (!json.contains("allow_rules")) return InvalidArgument("policy: \"allow_rules\" is missing");
  for (const char* field : {"allow_rules", "deny_rules"}) {
    if (!json.contains(field)) continue;
    const Json& rules = json[field];
    if (!rules.is_array()) return InvalidArgument(fmt::format("{}: not a list", field));
    for (std::size_t i = 0; i < rules.size(); ++i) {
      const std::string where = fmt::format("{}[{}]", field, i);
      auto rule = ParseRule(&rules[i], where);
      if (!rule.ok()) return rule.status();
      if (Status s = CheckPaths(rule->paths, methods, where); !s.ok()) return s;
      (field[0] == 'a' ? policy.allow_ : policy.deny_).push_back(std::move(rule).value());
    }
  }
  return policy;
}

AuthorizationPolicy::Decision AuthorizationPolicy::Evaluate(const Peer& peer,
                                                            std::string_view path) const {
  for (const Rule& rule : deny_) {
    if (rule.Matches(peer, path)) return {false, rule.name};
  }
  for (const Rule& rule : allow_) {
    if (rule.Matches(peer, path)) return {true, rule.name};
  }
  return {false, ""};
}

}  // namespace skinserve::server
