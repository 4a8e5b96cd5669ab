#include "gpu/gpu_region_service.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>

#include "rpc/server_messages.h"

namespace skinserve::server {
namespace {

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* context, const Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(ToGrpc(status));
  return reactor;
}

const Status kWarmingUp = Unavailable("the server is starting: backends are being built");

void ToWire(const GpuRegionInfo& info, v1::GpuRegionInfo* wire) {
  wire->set_name(info.name);
  wire->set_byte_size(info.byte_size);
  wire->set_backend(info.backend);
  wire->set_frames_written(info.frames_written);
  wire->set_idle_seconds(info.idle_seconds);
  wire->set_signals_semaphore(info.signals_semaphore);
}

}  // namespace

Status GpuRegionService::Authorize(const grpc::CallbackServerContext& context,
                                   const char* method) const {
  return server::Authorize(policy_, context, v1::GpuRegions::service_full_name(), method);
}

Result<GpuRegionInfo> GpuRegionService::Register(const v1::RegisterGpuRegionRequest& request,
                                                 const RegionOwner& owner, Engine& engine) {
  if (request.device_uuid().size() != 16) {
    return InvalidArgument(
        fmt::format("device_uuid holds {} bytes; it must be the device's 16-byte UUID "
                    "(VkPhysicalDeviceIDProperties.deviceUUID)",
                    request.device_uuid().size()));
  }
  Result<int> fd = handoff_->Take(request.fd_token(), owner);
  if (!fd.ok()) return fd.status();
  DeviceMemoryImport import{.fd = *fd, .byte_size = request.byte_size()};
  if (!request.semaphore_fd_token().empty()) {
    Result<int> semaphore = handoff_->Take(request.semaphore_fd_token(), owner);
    if (!semaphore.ok()) {
      close(*fd);
      return Status(semaphore.status().code(),
                    fmt::format("semaphore_fd_token: {}", semaphore.status().message()));
    }
    import.semaphore_fd = *semaphore;
  }
  std::copy_n(reinterpret_cast<const uint8_t*>(request.device_uuid().data()), 16,
              import.device_uuid.begin());
  const std::string backend = request.backend().empty() ? default_backend_ : request.backend();
  bool imported = false;
  Result<GpuRegionInfo> info = regions_->Register(request.name(), request.byte_size(), owner, [&] {
    Result<std::shared_ptr<DeviceMemory>> memory = engine.ImportDeviceMemory(backend, import);
    imported = memory.ok();
    return memory;
  });
  if (!imported) {  // on success the backend owns them
    close(import.fd);
    if (import.semaphore_fd >= 0) close(import.semaphore_fd);
  }
  return info;
}

grpc::ServerUnaryReactor* GpuRegionService::RegisterGpuRegion(
    grpc::CallbackServerContext* context, const v1::RegisterGpuRegionRequest* request,
    v1::GpuRegionInfo* response) {
  if (Status s = Authorize(*context, "RegisterGpuRegion"); !s.ok()) return Done(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, access_);
  if (!owner.ok()) return Done(context, owner.status());
  Result<GpuRegionInfo> info = Register(*request, *owner, *engine);
  if (info.ok()) ToWire(*info, response);
  return Done(context, info.status());
}

grpc::ServerUnaryReactor* GpuRegionService::UnregisterGpuRegion(
    grpc::CallbackServerContext* context, const v1::UnregisterGpuRegionRequest* request,
    v1::UnregisterGpuRegionResponse*) {
  if (Status s = Authorize(*context, "UnregisterGpuRegion"); !s.ok()) return Done(context, s);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, access_);
  if (!owner.ok()) return Done(context, owner.status());
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  // Answered once the last frame writing into the region is done and its import released.
  Status status = regions_->Unregister(request->name(), *owner,
                                       [reactor] { reactor->Finish(grpc::Status::OK); });
  if (!status.ok()) reactor->Finish(ToGrpc(status));
  return reactor;
}

grpc::ServerUnaryReactor* GpuRegionService::ListGpuRegions(grpc::CallbackServerContext* context,
                                                           const v1::ListGpuRegionsRequest*,
                                                           v1::ListGpuRegionsResponse* response) {
  if (Status s = Authorize(*context, "ListGpuRegions"); !s.ok()) return Done(context, s);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, access_);
  if (!owner.ok()) return Done(context, owner.status());
  for (const GpuRegionInfo& info : regions_->List(*owner)) ToWire(info, response->add_regions());
  response->set_budget_bytes(regions_->limits().budget_bytes);
  response->set_imported_bytes(regions_->imported_bytes());
  return Done(context, Status::Ok());
}

}  // namespace skinserve::server
