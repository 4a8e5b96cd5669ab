#include "backends/opencl/opencl_mesh_arena.h"

#include <algorithm>

namespace skinserve {

std::shared_ptr<OpenClMeshArena> OpenClMeshArena::Create(std::shared_ptr<OpenClRuntime> runtime,
                                                         std::size_t chunk_bytes) {
  return std::shared_ptr<OpenClMeshArena>(new OpenClMeshArena(std::move(runtime), chunk_bytes));
}

OpenClMeshArena::OpenClMeshArena(std::shared_ptr<OpenClRuntime> runtime, std::size_t chunk_bytes)
    : runtime_(std::move(runtime)),
      // At most 4 GiB: the tick kernels' offsets are 32-bit words.
      chunk_bytes_(
          std::min(chunk_bytes > 0 ? chunk_bytes : kDefaultChunkBytes, std::size_t{4} << 30)),
      alignment_(std::max<uint64_t>(runtime_->base_address_alignment(), 64)) {}

OpenClMeshArena::~OpenClMeshArena() {
  if (uploads_ != nullptr) clReleaseCommandQueue(uploads_);
}

Result<std::unique_ptr<OpenClMeshArena::Slice>> OpenClMeshArena::Allocate(uint64_t bytes) {
  bytes = (bytes + alignment_ - 1) / alignment_ * alignment_;
  if (bytes == 0 || bytes > chunk_bytes_ / 4) return std::unique_ptr<Slice>();
  std::lock_guard lock(mutex_);
  // First fit over the chunks in order: a mesh freed early leaves room for the next.
  for (std::size_t c = 0; c < chunks_.size(); ++c) {
    auto& free = chunks_[c]->free;
    for (auto it = free.begin(); it != free.end(); ++it) {
      if (it->second < bytes) continue;
      const uint64_t offset = it->first, left = it->second - bytes;
      free.erase(it);
      if (left > 0) free.emplace(offset + bytes, left);
      return std::make_unique<Slice>(shared_from_this(), c, chunks_[c]->buffer.get(), offset,
                                     bytes);
    }
  }
  if (uploads_ == nullptr) {
    cl_int err = CL_SUCCESS;
    uploads_ = clCreateCommandQueue(runtime_->context(), runtime_->device(), 0, &err);
    if (err != CL_SUCCESS) {
      uploads_ = nullptr;
      return ClError("clCreateCommandQueue(mesh uploads)", err);
    }
  }
  auto buffer = runtime_->CreateBuffer("mesh arena chunk", CL_MEM_READ_ONLY, chunk_bytes_, nullptr);
  if (!buffer.ok()) return buffer.status();
  auto chunk = std::make_unique<Chunk>();
  chunk->buffer = std::move(buffer).value();
  chunk->free.emplace(bytes, chunk_bytes_ - bytes);
  cl_mem mem = chunk->buffer.get();
  chunks_.push_back(std::move(chunk));
  return std::make_unique<Slice>(shared_from_this(), chunks_.size() - 1, mem, 0, bytes);
}

Status OpenClMeshArena::Write(const Slice& slice, uint64_t offset, const void* host,
                              std::size_t bytes) {
  if (bytes == 0) return Status::Ok();
  // Blocking: the host arrays need not outlive the call, and the mesh is on the device
  // before any frame can name it.
  if (cl_int err = clEnqueueWriteBuffer(uploads_, slice.chunk(), CL_TRUE, slice.offset() + offset,
                                        bytes, host, 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueWriteBuffer(mesh arena)", err);
  }
  return Status::Ok();
}

void OpenClMeshArena::Free(std::size_t chunk, uint64_t offset, uint64_t bytes) {
  std::lock_guard lock(mutex_);
  auto& free = chunks_[chunk]->free;
  auto next = free.lower_bound(offset);
  if (next != free.end() && offset + bytes == next->first) {  // merge with the block after
    bytes += next->second;
    next = free.erase(next);
  }
  if (next != free.begin()) {
    auto previous = std::prev(next);
    if (previous->first + previous->second == offset) {  // and with the block before
      previous->second += bytes;
      return;
    }
  }
  free.emplace(offset, bytes);
}

std::size_t OpenClMeshArena::chunk_count() const {
  std::lock_guard lock(mutex_);
  return chunks_.size();
}

}  // namespace skinserve
