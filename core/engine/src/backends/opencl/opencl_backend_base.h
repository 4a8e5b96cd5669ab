// Internal: what the two OpenCL backends share. Both hold the mesh in the same five buffers
// (and its morph targets), take the same palette layout, check the same outputs and enqueue
// the same kernels; they differ only in how their buffers meet host memory: `opencl`
// copies the mesh in once and the frame in and out (opencl_copy_backend.cpp),
// `opencl-zerocopy` wraps the caller's memory in place (opencl_zerocopy_backend.cpp).
#pragma once

#include <functional>
#include <memory>

#include "backends/opencl/opencl_encode.h"
#include "backends/opencl/opencl_mesh_arena.h"
#include "backends/opencl/opencl_morph.h"
#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// A mesh on the device: its float or quantized arrays (opencl_quantized.h) and its morph
// targets; normals and tangents only where the mesh has them.
struct OpenClPreparedMesh final : PreparedMesh {
  using PreparedMesh::PreparedMesh;
  // A float32 mesh of the copy backend: its arrays' place in the device mesh arena (else
  // null: buffers of their own), declared first so that it is given back after the
  // sub-buffers below are released; and each array's offset there in 4-byte words (the tick
  // kernels' table).
  std::unique_ptr<OpenClMeshArena::Slice> arena;
  uint32_t positions_word = 0, normals_word = 0, tangents_word = 0, joints_word = 0,
           weights_word = 0;
  ClBuffer positions, normals, tangents, joints, weights;
  OpenClMorphTargets morph;
};

class OpenClBackendBase : public Backend {
 public:
  const BackendInfo& info() const override { return info_; }
  // The mesh's buffers, created with `mesh_host_memory` (the prepared mesh holds the Mesh
  // alive, and with it any memory the buffers wrap).
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) final;
  // The frame's palette in the kernels' layout (a quantized mesh's box folded in, or dual
  // quaternions), its outputs checked against the mesh, then SkinPalette.
  Status Skin(const PreparedMesh& base, const SkinFrame& frame) final;

 protected:
  // `mesh_host_memory`: CL_MEM_COPY_HOST_PTR or CL_MEM_USE_HOST_PTR. `mesh_arena`: where
  // float32 meshes go (the copy backend's), or null: buffers of their own.
  OpenClBackendBase(std::shared_ptr<OpenClRuntime> runtime, std::shared_ptr<OpenClEncoder> encoder,
                    cl_mem_flags mesh_host_memory, BackendInfo info,
                    std::shared_ptr<OpenClMeshArena> mesh_arena = nullptr);

  // Skin() with frame.palette in the layout of frame.method's kernels and outputs the mesh has.
  virtual Status SkinPalette(const OpenClPreparedMesh& prepared, const SkinFrame& frame) = 0;

  // What Skin() does before SkinPalette (the kernels' palette layout, the outputs checked),
  // then `then` on the result, which may use the frame only within the call (a converted
  // palette lives until it returns).
  using InKernelLayoutFn = std::function<Status(const OpenClPreparedMesh&, const SkinFrame&)>;
  Status InKernelLayout(const PreparedMesh& base, const SkinFrame& frame,
                        const InKernelLayoutFn& then) const;

  // The lane's device output buffers large enough for the outputs `frame` asks for.
  Status GrowLaneOutputs(OpenClLane& lane, const SkinFrame& frame, uint32_t vertex_count) const;

  // The skinning kernel's arguments: the mesh's buffers, the frame's palette and outputs;
  // a null `out_normals` (`out_tangents`) leaves the normals (tangents) out.
  static SkinKernelArgs KernelArgs(const OpenClPreparedMesh& prepared, SkinningMethod method,
                                   cl_mem palette, cl_mem out_positions, cl_mem out_normals,
                                   cl_mem out_tangents);

  OpenClRuntime& runtime() const { return *runtime_; }
  OpenClEncoder& encoder() const { return *encoder_; }

 private:
  std::shared_ptr<OpenClRuntime> runtime_;
  // A float32 mesh's arrays as sub-buffers of its arena slice: false (and Ok) when the
  // arena has no room for meshes of its size.
  Result<bool> PrepareInArena(const Mesh& mesh, OpenClPreparedMesh* prepared);

  std::shared_ptr<OpenClEncoder> encoder_;
  cl_mem_flags mesh_host_memory_;
  BackendInfo info_;
  std::shared_ptr<OpenClMeshArena> mesh_arena_;
};

}  // namespace skinserve
