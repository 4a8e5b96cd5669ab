// The device mesh arena: `opencl`'s float32 meshes live in a few large device buffers
// (chunks) rather than in five buffers each, so that a tick's characters, whatever their
// meshes, run in one kernel launch that finds each mesh by its offsets in its chunk
// (kernels/tick_skinning.cl, opencl_tick_launch.h). A mesh's arrays are also sub-buffers of
// its chunk, so every single-frame path takes them as before. Chunks are created as meshes
// need them and never shrink; a mesh larger than a quarter of a chunk keeps buffers of its
// own (a large frame runs alone anyway).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "backends/opencl/opencl_runtime.h"

namespace skinserve {

class OpenClMeshArena : public std::enable_shared_from_this<OpenClMeshArena> {
 public:
  // `chunk_bytes`: each chunk's size (0: kDefaultChunkBytes).
  static std::shared_ptr<OpenClMeshArena> Create(std::shared_ptr<OpenClRuntime> runtime,
                                                 std::size_t chunk_bytes);
  ~OpenClMeshArena();
  OpenClMeshArena(const OpenClMeshArena&) = delete;
  OpenClMeshArena& operator=(const OpenClMeshArena&) = delete;
  static constexpr std::size_t kDefaultChunkBytes = std::size_t{128} << 20;

  // A mesh's bytes in a chunk, given back to the arena when destroyed (after the mesh's
  // sub-buffers of it: OpenClPreparedMesh declares it first).
  class Slice {
   public:
    Slice(std::shared_ptr<OpenClMeshArena> arena, std::size_t chunk, cl_mem buffer, uint64_t offset,
          uint64_t bytes)
        : arena_(std::move(arena)),
          chunk_(chunk),
          buffer_(buffer),
          offset_(offset),
          bytes_(bytes) {}
    ~Slice() { arena_->Free(chunk_, offset_, bytes_); }
    Slice(const Slice&) = delete;
    Slice& operator=(const Slice&) = delete;
    cl_mem chunk() const { return buffer_; }  // a chunk's buffer lives as long as the arena
    uint64_t offset() const { return offset_; }

   private:
    std::shared_ptr<OpenClMeshArena> arena_;
    std::size_t chunk_;
    cl_mem buffer_;
    uint64_t offset_, bytes_;
  };

  // The bytes of one mesh's arrays (each array's start a multiple of alignment()), or null
  // (and Ok) when the mesh is too large for a chunk. A new chunk's allocation failure
  // passes through (RESOURCE_EXHAUSTED on out-of-memory).
  Result<std::unique_ptr<Slice>> Allocate(uint64_t bytes);
  // Where every array in a slice must start: the device's base-address alignment (a
  // sub-buffer's origin) and at least 64 bytes (the kernels' vector loads).
  uint64_t alignment() const { return alignment_; }
  // Writes `bytes` from `host` at `offset` of `slice`, waited for.
  Status Write(const Slice& slice, uint64_t offset, const void* host, std::size_t bytes);
  // Chunks created so far (for tests).
  std::size_t chunk_count() const;

 private:
  OpenClMeshArena(std::shared_ptr<OpenClRuntime> runtime, std::size_t chunk_bytes);
  void Free(std::size_t chunk, uint64_t offset, uint64_t bytes);

  struct Chunk {
    ClBuffer buffer;
    std::map<uint64_t, uint64_t> free;  // offset -> bytes, never adjacent (merged on Free)
  };
  std::shared_ptr<OpenClRuntime> runtime_;  // the chunks' context outlives them
  const std::size_t chunk_bytes_;
  const uint64_t alignment_;
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Chunk>> chunks_;
  cl_command_queue uploads_ = nullptr;  // Write's own queue: uploads wait for no lane
};

}  // namespace skinserve
