// Morph targets on the OpenCL backends: a mesh's sparse targets on the device once per mesh,
// beside its rest arrays, and per frame the morph kernel (kernels/morph_targets.cl) that
// writes the frame's morphed rest arrays into the lane's buffers, which the skinning kernel
// then reads instead of the mesh's. Only the frame's active weights cross per frame; a frame
// without an active target enqueues nothing and skins the mesh's arrays as before.
#pragma once

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// A mesh's targets on the device; empty buffers for a mesh without targets (or without
// normal or tangent deltas).
struct OpenClMorphTargets {
  ClBuffer offsets, indices, position_deltas, normal_deltas, tangent_deltas;
};

// The mesh's targets as buffers created with `flags`: CL_MEM_COPY_HOST_PTR (the `opencl`
// backend: a device copy) or CL_MEM_USE_HOST_PTR (`opencl-zerocopy`: the mesh's own arrays
// in place; the prepared mesh keeps the Mesh alive).
Result<OpenClMorphTargets> CreateMorphTargets(OpenClRuntime& runtime, const Mesh& mesh,
                                              cl_mem_flags flags);

// Whether `frame` morphs on the device: it has an active target, and the mesh's targets
// move vertices (targets without a delta leave the rest arrays as they are).
bool MorphsOnDevice(const SkinFrame& frame, const OpenClMorphTargets& targets);

// For a frame that MorphsOnDevice: enqueues on `lane`'s compute queue the morph of the
// mesh's rest arrays (`args`' positions, normals and tangents, as the prepared mesh holds
// them) by the frame's weights, which `weights` holds (frame.morph_weights' entries, on the
// device or wrapped in place), into the lane's morphed buffers, and points `args` at those.
// Normals and tangents are each morphed when the frame asks for them and the targets move
// them; otherwise `args` keeps the mesh's. The kernel's event goes to `kernels`. Any other frame:
// nothing.
Status EnqueueFrameMorph(OpenClRuntime& runtime, OpenClLane& lane, const Mesh& mesh,
                         const OpenClMorphTargets& targets, cl_mem weights, const SkinFrame& frame,
                         SkinKernelArgs* args, ClEvents& kernels);

}  // namespace skinserve
