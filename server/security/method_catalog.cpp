#include "security/method_catalog.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <google/protobuf/descriptor.h>

#include <algorithm>
#include <stdexcept>

#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {
namespace {

// gRPC's own services: health as gRPC implements it (without a protobuf descriptor in this
// process), reflection as grpc++_reflection serves it.
constexpr const char* kGrpcPaths[] = {
    "/grpc.health.v1.Health/Check",
    "/grpc.health.v1.Health/Watch",
    "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
};

// Every method of every service in the file that declares skinserve.v1.Skinning.
std::vector<std::string> SkinservePaths() {
  const google::protobuf::ServiceDescriptor* skinning =
      google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(
          v1::Skinning::service_full_name());
  if (skinning == nullptr) throw std::logic_error("skinning.proto's descriptors are not linked");
  std::vector<std::string> paths;
  const google::protobuf::FileDescriptor* file = skinning->file();
  for (int s = 0; s < file->service_count(); ++s) {
    const google::protobuf::ServiceDescriptor* service = file->service(s);
    for (int m = 0; m < service->method_count(); ++m) {
      paths.push_back(fmt::format("/{}/{}", service->full_name(), service->method(m)->name()));
    }
  }
  return paths;
}

// "/a.B/C" -> "a.B"; "" when `path` has no service part.
std::string_view ServiceOf(std::string_view path) {
  if (!path.starts_with('/')) return {};
  const std::size_t slash = path.find('/', 1);
  return slash == std::string_view::npos ? std::string_view() : path.substr(1, slash - 1);
}

}  // namespace

const MethodCatalog& MethodCatalog::Served() {
  static const MethodCatalog served = [] {
    std::vector<std::string> paths = SkinservePaths();
    paths.insert(paths.end(), std::begin(kGrpcPaths), std::end(kGrpcPaths));
    return MethodCatalog(std::move(paths));
  }();
  return served;
}

MethodCatalog::MethodCatalog(std::vector<std::string> paths) : paths_(std::move(paths)) {
  std::sort(paths_.begin(), paths_.end());
}

bool MethodCatalog::Contains(std::string_view path) const {
  return std::binary_search(paths_.begin(), paths_.end(), path);
}

std::string MethodCatalog::Known(std::string_view path) const {
  const std::string_view service = ServiceOf(path);
  std::vector<std::string_view> methods, services;
  for (const std::string& known : paths_) {
    const std::string_view known_service = ServiceOf(known);
    if (!service.empty() && known_service == service) {
      methods.push_back(std::string_view(known).substr(service.size() + 2));
    }
    if (services.empty() || services.back() != known_service) services.push_back(known_service);
  }
  if (!methods.empty()) return fmt::format("{} has {}", service, fmt::join(methods, ", "));
  return fmt::format("the services are {}", fmt::join(services, ", "));
}

}  // namespace skinserve::server
