#include "backends/opencl/opencl_backend_base.h"

#include <fmt/format.h>

#include <vector>

#include "backends/common/dual_quaternion_palette.h"
#include "backends/opencl/opencl_quantized.h"

namespace skinserve {
namespace {

// Both backends' Skin(): `frame` with its palette in the layout the kernels take - folded
// with a quantized mesh's box (after CheckQuantizedMethod), or
// as unit dual quaternions, converted once per frame - handed to `skin_palette`.
template <typename SkinPalette>
Status SkinWithKernelPalette(const std::string& backend_id, const PreparedMesh& base,
                             const SkinFrame& frame, const SkinPalette& skin_palette) {
  if (const QuantizedRest* rest = base.mesh().quantized_rest()) {
    if (Status s = CheckQuantizedMethod(backend_id, base.mesh(), frame.method); !s.ok()) return s;
    SkinFrame folded = frame;
    folded.palette = FoldedQuantizedPalette(frame.palette, *rest);
    return skin_palette(folded);
  }
  if (frame.method == SkinningMethod::kDualQuaternion) {
    const DualQuaternionPalette quaternions(frame.palette);
    SkinFrame converted = frame;
    converted.palette = quaternions.floats();
    return skin_palette(converted);
  }
  return skin_palette(frame);
}

// INVALID_ARGUMENT when `frame` asks for normals or tangents that `mesh` does not have
// (tangents come with normals).
Status CheckOpenClOutputs(const Mesh& mesh, const SkinFrame& frame) {
  if (frame.wants_normals() && !mesh.has_normals()) {
    return InvalidArgument("normals requested, but the mesh has none");
  }
  if (frame.wants_tangents() && (!mesh.has_tangents() || !frame.wants_normals())) {
    return InvalidArgument(
        "tangents requested, but the mesh has none or normals are not asked for");
  }
  return Status::Ok();
}

}  // namespace

OpenClBackendBase::OpenClBackendBase(std::shared_ptr<OpenClRuntime> runtime,
                                     std::shared_ptr<OpenClEncoder> encoder,
                                     cl_mem_flags mesh_host_memory, BackendInfo info,
                                     std::shared_ptr<OpenClMeshArena> mesh_arena)
    : runtime_(std::move(runtime)),
      encoder_(std::move(encoder)),
      mesh_host_memory_(mesh_host_memory),
      info_(std::move(info)),
      mesh_arena_(std::move(mesh_arena)) {}

Result<std::unique_ptr<PreparedMesh>> OpenClBackendBase::Prepare(std::shared_ptr<const Mesh> mesh) {
  auto prepared = std::make_unique<OpenClPreparedMesh>(mesh);
  if (mesh->quantized_rest() != nullptr) {  // the integers only (opencl_quantized.h)
    if (Status s = PrepareQuantizedMesh(*runtime_, *mesh, mesh_host_memory_, &prepared->positions,
                                        &prepared->normals, &prepared->tangents, &prepared->joints,
                                        &prepared->weights);
        !s.ok()) {
      return s;
    }
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }
  auto in_arena = PrepareInArena(*mesh, prepared.get());
  if (!in_arena.ok()) return in_arena.status();
  if (*in_arena) {
    auto morph = CreateMorphTargets(*runtime_, *mesh, mesh_host_memory_);
    if (!morph.ok()) return morph.status();
    prepared->morph = std::move(morph).value();
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }
  struct Plan {
    const char* what;
    ClBuffer* buffer;
    std::size_t bytes;
    const void* host;
  };
  std::vector<Plan> plan = {
      {"positions", &prepared->positions, mesh->positions().size_bytes(), mesh->positions().data()},
      {"joints", &prepared->joints, mesh->joints().size_bytes(), mesh->joints().data()},
      {"weights", &prepared->weights, mesh->weights().size_bytes(), mesh->weights().data()}};
  if (mesh->has_normals()) {
    plan.push_back(
        {"normals", &prepared->normals, mesh->normals().size_bytes(), mesh->normals().data()});
  }
  if (mesh->has_tangents()) {
    plan.push_back(
        {"tangents", &prepared->tangents, mesh->tangents().size_bytes(), mesh->tangents().data()});
  }
  for (const Plan& p : plan) {
    auto buffer =
        runtime_->CreateBuffer(p.what, CL_MEM_READ_ONLY | mesh_host_memory_, p.bytes, p.host);
    if (!buffer.ok()) return buffer.status();
    *p.buffer = std::move(buffer).value();
  }
  auto morph = CreateMorphTargets(*runtime_, *mesh, mesh_host_memory_);
  if (!morph.ok()) return morph.status();
  prepared->morph = std::move(morph).value();
  return std::unique_ptr<PreparedMesh>(std::move(prepared));
}

Result<bool> OpenClBackendBase::PrepareInArena(const Mesh& mesh, OpenClPreparedMesh* prepared) {
  if (mesh_arena_ == nullptr) return false;
  struct Array {
    const char* what;
    ClBuffer* buffer;
    uint32_t* word;
    std::size_t bytes;
    const void* host;
    uint64_t offset = 0;
  };
  std::vector<Array> arrays = {{"positions", &prepared->positions, &prepared->positions_word,
                                mesh.positions().size_bytes(), mesh.positions().data()},
                               {"joints", &prepared->joints, &prepared->joints_word,
                                mesh.joints().size_bytes(), mesh.joints().data()},
                               {"weights", &prepared->weights, &prepared->weights_word,
                                mesh.weights().size_bytes(), mesh.weights().data()}};
  if (mesh.has_normals()) {
    arrays.push_back({"normals", &prepared->normals, &prepared->normals_word,
                      mesh.normals().size_bytes(), mesh.normals().data()});
  }
  if (mesh.has_tangents()) {
    arrays.push_back({"tangents", &prepared->tangents, &prepared->tangents_word,
                      mesh.tangents().size_bytes(), mesh.tangents().data()});
  }
  const uint64_t align = mesh_arena_->alignment();
  uint64_t total = 0;
  for (Array& a : arrays) {
    a.offset = total;
    total += (a.bytes + align - 1) / align * align;
  }
  auto slice = mesh_arena_->Allocate(total);
  if (!slice.ok()) return slice.status();
  if (*slice == nullptr) return false;
  // Held by the mesh from here: after an error, its sub-buffers go before the slice.
  prepared->arena = std::move(slice).value();
  const OpenClMeshArena::Slice& held = *prepared->arena;
  for (const Array& a : arrays) {
    const cl_buffer_region region{held.offset() + a.offset, a.bytes};
    cl_int err = CL_SUCCESS;
    cl_mem sub = clCreateSubBuffer(held.chunk(), CL_MEM_READ_ONLY, CL_BUFFER_CREATE_TYPE_REGION,
                                   &region, &err);
    if (err != CL_SUCCESS) {
      return ClError(fmt::format("clCreateSubBuffer(mesh {})", a.what).c_str(), err);
    }
    *a.buffer = ClBuffer(sub);
    if (Status s = mesh_arena_->Write(held, a.offset, a.host, a.bytes); !s.ok()) return s;
    *a.word = static_cast<uint32_t>((held.offset() + a.offset) / sizeof(uint32_t));
  }
  return true;
}

Status OpenClBackendBase::Skin(const PreparedMesh& base, const SkinFrame& frame) {
  return InKernelLayout(
      base, frame, [this](const OpenClPreparedMesh& prepared, const SkinFrame& in_kernel_layout) {
        return SkinPalette(prepared, in_kernel_layout);
      });
}

Status OpenClBackendBase::InKernelLayout(const PreparedMesh& base, const SkinFrame& frame,
                                         const InKernelLayoutFn& then) const {
  const auto& prepared = static_cast<const OpenClPreparedMesh&>(base);
  return SkinWithKernelPalette(info_.id, base, frame, [&](const SkinFrame& in_kernel_layout) {
    if (Status s = CheckOpenClOutputs(prepared.mesh(), in_kernel_layout); !s.ok()) return s;
    return then(prepared, in_kernel_layout);
  });
}

Status OpenClBackendBase::GrowLaneOutputs(OpenClLane& lane, const SkinFrame& frame,
                                          uint32_t vertex_count) const {
  const std::size_t out_bytes = 3ull * vertex_count * sizeof(float);
  const std::size_t tangent_bytes = 4ull * vertex_count * sizeof(float);
  if (Status s = runtime_->GrowBuffer("output positions", CL_MEM_READ_WRITE, out_bytes,
                                      &lane.out_positions, &lane.positions_bytes);
      !s.ok()) {
    return s;
  }
  if (frame.wants_normals()) {
    if (Status s = runtime_->GrowBuffer("output normals", CL_MEM_READ_WRITE, out_bytes,
                                        &lane.out_normals, &lane.normals_bytes);
        !s.ok()) {
      return s;
    }
  }
  if (frame.wants_tangents()) {
    return runtime_->GrowBuffer("output tangents", CL_MEM_READ_WRITE, tangent_bytes,
                                &lane.out_tangents, &lane.tangents_bytes);
  }
  return Status::Ok();
}

SkinKernelArgs OpenClBackendBase::KernelArgs(const OpenClPreparedMesh& prepared,
                                             SkinningMethod method, cl_mem palette,
                                             cl_mem out_positions, cl_mem out_normals,
                                             cl_mem out_tangents) {
  SkinKernelArgs args{.method = method,
                      .palette = palette,
                      .joints = prepared.joints.get(),
                      .weights = prepared.weights.get(),
                      .positions = prepared.positions.get(),
                      .out_positions = out_positions};
  if (out_normals != nullptr) {
    args.normals = prepared.normals.get();
    args.out_normals = out_normals;
  }
  if (out_tangents != nullptr) {
    args.tangents = prepared.tangents.get();
    args.out_tangents = out_tangents;
  }
  return args;
}

}  // namespace skinserve
