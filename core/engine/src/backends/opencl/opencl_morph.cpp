#include "backends/opencl/opencl_morph.h"

namespace skinserve {

Result<OpenClMorphTargets> CreateMorphTargets(OpenClRuntime& runtime, const Mesh& mesh,
                                              cl_mem_flags flags) {
  OpenClMorphTargets targets;
  if (mesh.morph_target_count() == 0) return targets;
  auto create = [&](const char* what, ClBuffer* buffer, auto span) -> Status {
    auto created =
        runtime.CreateBuffer(what, CL_MEM_READ_ONLY | flags, span.size_bytes(), span.data());
    if (!created.ok()) return created.status();
    *buffer = std::move(created).value();
    return Status::Ok();
  };
  if (Status s = create("morph offsets", &targets.offsets, mesh.morph_offsets()); !s.ok()) return s;
  // A mesh may have targets that move no vertex: no delta at all, and no zero-size buffer.
  if (mesh.morph_indices().empty()) return targets;
  if (Status s = create("morph indices", &targets.indices, mesh.morph_indices()); !s.ok()) return s;
  if (Status s =
          create("morph position deltas", &targets.position_deltas, mesh.morph_position_deltas());
      !s.ok()) {
    return s;
  }
  if (mesh.has_morph_normals()) {
    if (Status s =
            create("morph normal deltas", &targets.normal_deltas, mesh.morph_normal_deltas());
        !s.ok()) {
      return s;
    }
  }
  if (mesh.has_morph_tangents()) {
    if (Status s =
            create("morph tangent deltas", &targets.tangent_deltas, mesh.morph_tangent_deltas());
        !s.ok()) {
      return s;
    }
  }
  return targets;
}

bool MorphsOnDevice(const SkinFrame& frame, const OpenClMorphTargets& targets) {
  return targets.indices.get() != nullptr && HasActiveMorph(frame.morph_weights);
}

Status EnqueueFrameMorph(OpenClRuntime& runtime, OpenClLane& lane, const Mesh& mesh,
                         const OpenClMorphTargets& targets, cl_mem weights, const SkinFrame& frame,
                         SkinKernelArgs* args, ClEvents& kernels) {
  if (!MorphsOnDevice(frame, targets)) return Status::Ok();
  const bool morph_normals = args->out_normals != nullptr && targets.normal_deltas.get() != nullptr;
  const bool morph_tangents =
      args->out_tangents != nullptr && targets.tangent_deltas.get() != nullptr;
  const std::size_t bytes = 3ull * mesh.vertex_count() * sizeof(float);  // encoded frames too
  if (Status s = runtime.GrowBuffer("morphed positions", CL_MEM_READ_WRITE, bytes,
                                    &lane.morphed_positions, &lane.morphed_positions_bytes);
      !s.ok()) {
    return s;
  }
  if (morph_normals) {
    if (Status s = runtime.GrowBuffer("morphed normals", CL_MEM_READ_WRITE, bytes,
                                      &lane.morphed_normals, &lane.morphed_normals_bytes);
        !s.ok()) {
      return s;
    }
  }
  if (morph_tangents) {
    if (Status s = runtime.GrowBuffer("morphed tangents", CL_MEM_READ_WRITE,
                                      4ull * mesh.vertex_count() * sizeof(float),
                                      &lane.morphed_tangents, &lane.morphed_tangents_bytes);
        !s.ok()) {
      return s;
    }
  }
  MorphKernelArgs morph{.positions = args->positions,
                        .offsets = targets.offsets.get(),
                        .indices = targets.indices.get(),
                        .position_deltas = targets.position_deltas.get(),
                        .weights = weights,
                        .weight_count = static_cast<cl_uint>(frame.morph_weights.size()),
                        .morphed_positions = lane.morphed_positions.get()};
  if (morph_normals) {
    morph.normals = args->normals;
    morph.normal_deltas = targets.normal_deltas.get();
    morph.morphed_normals = lane.morphed_normals.get();
  }
  if (morph_tangents) {
    morph.tangents = args->tangents;
    morph.tangent_deltas = targets.tangent_deltas.get();
    morph.morphed_tangents = lane.morphed_tangents.get();
  }
  if (Status s = runtime.EnqueueMorph(lane, mesh.vertex_count(), morph, kernels.Next()); !s.ok())
    return s;
  args->positions = lane.morphed_positions.get();
  if (morph_normals) args->normals = lane.morphed_normals.get();
  if (morph_tangents) args->tangents = lane.morphed_tangents.get();
  return Status::Ok();
}

}  // namespace skinserve
