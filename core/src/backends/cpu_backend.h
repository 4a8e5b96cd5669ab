// CpuBackend: a backend made of one skinning kernel over vertex ranges, run on the
// calling thread (info.threads == 1) or split across info.threads OpenMP threads. The
// four CPU backends differ only in the kernel and the description.
#pragma once

#include <algorithm>
#include <new>

#include "parallel_range.h"
#include "skinserve/core/backend.h"

namespace skinserve {

// A Kernel provides
//  - Kernel::FramePalette, constructible from the frame's palette: the palette in the
//    kernel's own layout, built once per frame on the calling thread and then only read;
//  - Kernel::SkinRange(const Mesh&, const FramePalette&, const SkinFrame&, first, last),
//    which writes exactly the outputs of vertices [first, last).
template <typename Kernel>
class CpuBackend final : public Backend {
 public:
  explicit CpuBackend(BackendInfo info) : info_(std::move(info)) {
    info_.min_threads = 1;  // a parallel loop runs on as few threads as it is given
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));  // skins the Mesh's own layout
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    const Mesh& mesh = prepared.mesh();
    try {
      const typename Kernel::FramePalette palette(frame.palette);
      const int threads =
          frame.threads > 0 ? std::min(frame.threads, info_.threads) : info_.threads;
      if (threads <= 1) {
        Kernel::SkinRange(mesh, palette, frame, 0, mesh.vertex_count());
      } else {
        ParallelOverVertices(mesh.vertex_count(), threads,
                             [&](std::size_t first, std::size_t last) {
                               Kernel::SkinRange(mesh, palette, frame, first, last);
                             });
      }
    } catch (const std::bad_alloc&) {  // a palette layout larger than any seen so far
      return ResourceExhausted(info_.id + ": out of memory for the frame's palette");
    }
    return Status::Ok();
  }

 private:
  BackendInfo info_;
};

}  // namespace skinserve
