// CpuBackend: a backend made of skinning kernels over vertex ranges, run on the calling
// thread (info.threads == 1) or split across info.threads OpenMP threads: a linear blend
// kernel and, optionally, a dual-quaternion one. The CPU backends differ only in the
// kernels and the description.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <new>
#include <type_traits>

#include "backends/common/morph_stage.h"
#include "backends/common/parallel_range.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// A Kernel provides
//  - Kernel::FramePalette, constructible from the frame's palette: the palette in the
//    kernel's own layout, built once per frame on the calling thread and then only read;
//  - Kernel::SkinRange(const Mesh&, const FramePalette&, const SkinFrame&, first, last),
//    which writes exactly the outputs of vertices [first, last).
// DualQuaternionKernel is such a kernel for dual-quaternion skinning, or void when the
// backend implements linear blend skinning only.
template <typename Kernel, typename DualQuaternionKernel = void>
class CpuBackend final : public Backend {
 public:
  explicit CpuBackend(BackendInfo info) : info_(std::move(info)) {
    info_.min_threads = 1;       // a parallel loop runs on as few threads as it is given
    info_.morph_targets = true;  // the morph stage feeds every kernel (morph_stage.h)
    info_.tangents = true;       // every kernel skins tangents with the normals
    info_.methods = {SkinningMethod::kLinear};
    if constexpr (!std::is_void_v<DualQuaternionKernel>) {
      info_.methods.push_back(SkinningMethod::kDualQuaternion);
    }
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    return std::make_unique<PreparedMesh>(std::move(mesh));  // skins the Mesh's own layout
  }
  Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) override {
    if (frame.method == SkinningMethod::kDualQuaternion) {
      if constexpr (!std::is_void_v<DualQuaternionKernel>) {
        return Run<DualQuaternionKernel>(prepared.mesh(), frame);
      } else {
        return InvalidArgument(fmt::format("backend '{}' does not implement {} skinning", info_.id,
                                           MethodName(frame.method)));
      }
    }
    return Run<Kernel>(prepared.mesh(), frame);
  }

 private:
  template <typename K>
  Status Run(const Mesh& mesh, const SkinFrame& frame) {
    try {
      const typename K::FramePalette palette(frame.palette);
      const int threads = FrameThreads(frame.threads, info_.threads);
      // The kernel skins each range from the rest arrays the morph stage hands it.
      const auto skin_range = [&](std::size_t first, std::size_t last) {
        ForEachMorphedRange(mesh, frame, first, last,
                            [&](const RestArrays& rest, std::size_t from, std::size_t to) {
                              SkinFrame morphed = frame;
                              morphed.rest_positions = rest.positions;
                              morphed.rest_normals = rest.normals;
                              morphed.rest_tangents = rest.tangents;
                              morphed.rest_first = rest.first;
                              K::SkinRange(mesh, palette, morphed, from, to);
                            });
      };
      if (threads <= 1) {
        skin_range(0, mesh.vertex_count());
      } else {
        ParallelOverVertices(mesh.vertex_count(), threads, skin_range);
      }
    } catch (const std::bad_alloc&) {  // a palette or morph scratch larger than any seen so far
      return ResourceExhausted(info_.id +
                               ": out of memory for the frame's palette or morph scratch");
    }
    return Status::Ok();
  }

  BackendInfo info_;
};

}  // namespace skinserve
