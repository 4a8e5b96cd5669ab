// clCreateCommandQueueWithProperties is OpenCL 2.0; the rest of the engine targets 1.2.
#undef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 300

#include "backends/opencl/opencl_semaphore.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "backends/opencl/opencl_runtime.h"

namespace skinserve {
namespace {

bool HasExtension(const std::string& extensions, const char* name) {
  const std::string padded = " " + extensions + " ";
  return padded.find(std::string(" ") + name + " ") != std::string::npos;
}

template <typename Fn>
Fn Extension(cl_platform_id platform, const char* name) {
  return reinterpret_cast<Fn>(clGetExtensionFunctionAddressForPlatform(platform, name));
}

}  // namespace

const char* MissingImportExtension(const std::string& extensions, bool with_semaphore) {
  for (const char* needed :
       {"cl_khr_external_memory", "cl_khr_external_memory_opaque_fd", "cl_khr_device_uuid"}) {
    if (!HasExtension(extensions, needed)) return needed;
  }
  if (!with_semaphore) return nullptr;
  for (const char* needed :
       {"cl_khr_semaphore", "cl_khr_external_semaphore", "cl_khr_external_semaphore_opaque_fd"}) {
    if (!HasExtension(extensions, needed)) return needed;
  }
  return nullptr;
}

Result<std::unique_ptr<ImportedSemaphore>> ImportedSemaphore::Import(const OpenClRuntime& runtime,
                                                                     int fd) {
  cl_platform_id platform = nullptr;
  if (cl_int err = clGetDeviceInfo(runtime.device(), CL_DEVICE_PLATFORM, sizeof(platform),
                                   &platform, nullptr);
      err != CL_SUCCESS) {
    return ClError("clGetDeviceInfo(CL_DEVICE_PLATFORM)", err);
  }
  auto create = Extension<clCreateSemaphoreWithPropertiesKHR_fn>(
      platform, "clCreateSemaphoreWithPropertiesKHR");
  std::unique_ptr<ImportedSemaphore> s(new ImportedSemaphore());
  s->signal_ = Extension<clEnqueueSignalSemaphoresKHR_fn>(platform, "clEnqueueSignalSemaphoresKHR");
  s->release_ = Extension<clReleaseSemaphoreKHR_fn>(platform, "clReleaseSemaphoreKHR");
  if (create == nullptr || s->signal_ == nullptr || s->release_ == nullptr) {
    return FailedPrecondition(fmt::format(
        "the opencl backend's device '{}' lists cl_khr_semaphore but its platform has no "
        "clCreateSemaphoreWithPropertiesKHR / clEnqueueSignalSemaphoresKHR / "
        "clReleaseSemaphoreKHR",
        runtime.device_name()));
  }
  // The driver may keep the descriptor it imports: it gets a duplicate, and a failed
  // registration leaves the caller's fd as it was.
  const int own = fcntl(fd, F_DUPFD_CLOEXEC, 0);
  if (own < 0) return Internal(fmt::format("dup of the semaphore fd: {}", std::strerror(errno)));
  // The context has the one device: no device list, as for the memory.
  const cl_semaphore_properties_khr properties[] = {
      CL_SEMAPHORE_TYPE_KHR, CL_SEMAPHORE_TYPE_BINARY_KHR, CL_SEMAPHORE_HANDLE_OPAQUE_FD_KHR,
      static_cast<cl_semaphore_properties_khr>(own), 0};
  cl_int err = CL_SUCCESS;
  s->semaphore_ = create(runtime.context(), properties, &err);
  if (err != CL_SUCCESS || s->semaphore_ == nullptr) {
    close(own);  // not imported: still ours
    s->semaphore_ = nullptr;
    return ClError("clCreateSemaphoreWithPropertiesKHR(binary, opaque fd)", err);
  }
  s->queue_ =
      clCreateCommandQueueWithProperties(runtime.context(), runtime.device(), nullptr, &err);
  if (err != CL_SUCCESS) {
    s->queue_ = nullptr;
    return ClError("clCreateCommandQueueWithProperties(semaphore signals)", err);
  }
  return s;
}

ImportedSemaphore::~ImportedSemaphore() {
  if (queue_ != nullptr) {
    clFinish(queue_);
    clReleaseCommandQueue(queue_);
  }
  if (semaphore_ != nullptr) release_(semaphore_);
}

Status ImportedSemaphore::Signal() {
  std::lock_guard lock(mutex_);
  if (cl_int err = signal_(queue_, 1, &semaphore_, nullptr, 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueSignalSemaphoresKHR", err);
  }
  if (cl_int err = clFlush(queue_); err != CL_SUCCESS) return ClError("clFlush(semaphore)", err);
  return Status::Ok();
}

}  // namespace skinserve
