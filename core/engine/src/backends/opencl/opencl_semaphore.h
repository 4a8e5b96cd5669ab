// An exported binary semaphore imported into the `opencl` backend's context for a GPU
// region (docs/serving/gpu-regions.md#semaphore): a Vulkan semaphore exported as an opaque
// file descriptor (VK_KHR_external_semaphore_fd), imported with cl_khr_semaphore and
// cl_khr_external_semaphore_opaque_fd, and signalled once per frame written into the
// region, on a queue of its own, after the frame's copies and their release are done.
#pragma once

#include <CL/cl.h>
#include <CL/cl_ext.h>

#include <memory>
#include <mutex>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve {

class OpenClRuntime;

// The extensions an import needs, in the order they are checked: the memory's, then (with
// a semaphore) the semaphore's. The first that `extensions` (CL_DEVICE_EXTENSIONS) lacks,
// or null when it has them all.
const char* MissingImportExtension(const std::string& extensions, bool with_semaphore);

class ImportedSemaphore {
 public:
  // Imports `fd`, a binary semaphore's opaque fd: the driver gets a duplicate, `fd` stays
  // the caller's either way. FAILED_PRECONDITION when the platform lacks an
  // entry point; the driver's error otherwise.
  static Result<std::unique_ptr<ImportedSemaphore>> Import(const OpenClRuntime& runtime, int fd);
  ~ImportedSemaphore();
  ImportedSemaphore(const ImportedSemaphore&) = delete;
  ImportedSemaphore& operator=(const ImportedSemaphore&) = delete;

  // Enqueues one signal and flushes it to the device, so that a wait the client submits
  // after the frame's answer has a signal submitted before it. Call only once the frame's
  // writes have finished (DeviceOutputBatch::Finish waits for them).
  Status Signal();

 private:
  ImportedSemaphore() = default;
  cl_semaphore_khr semaphore_ = nullptr;
  cl_command_queue queue_ = nullptr;
  clEnqueueSignalSemaphoresKHR_fn signal_ = nullptr;
  clReleaseSemaphoreKHR_fn release_ = nullptr;
  std::mutex mutex_;  // signals in the order frames finish
};

}  // namespace skinserve
