// MethodCatalog: the methods an authorization policy may name, as gRPC paths
// ("/skinserve.v1.GpuRegions/RegisterGpuRegion"), so that a path naming none of them (a
// typo, a method of another version) is refused when the policy loads rather than matching
// nothing for ever. Served() reads every service declared in skinning.proto from its
// descriptors, so a service added there is known without a list to update; to them it
// adds gRPC's health and reflection services, which the server answers but the policy does
// not govern (health is open to the probes, reflection on or off as a whole).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace skinserve::server {

class MethodCatalog {
 public:
  static const MethodCatalog& Served();
  explicit MethodCatalog(std::vector<std::string> paths);

  // "/package.Service/Method", sorted.
  const std::vector<std::string>& paths() const { return paths_; }
  bool Contains(std::string_view path) const;
  // For a refusal: the methods of the service `path` names ("skinserve.v1.GpuRegions has
  // RegisterGpuRegion, ..."), or the services there are when it names none.
  std::string Known(std::string_view path) const;

 private:
  std::vector<std::string> paths_;
};

}  // namespace skinserve::server
