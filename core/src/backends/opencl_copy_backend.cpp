// `opencl`: the paper's plain OpenCL path. The mesh is copied into device buffers once;
// each frame writes the palette to the device and reads the result back.
#include <vector>

#include "opencl_backends.h"
#include "skinserve/core/palette.h"

namespace skinserve {
namespace {

struct OpenClPreparedMesh final : PreparedMesh {
  using PreparedMesh::PreparedMesh;
  ClBuffer positions, normals, joints, weights;
  // Per-frame traffic, reused by every frame (frames are serialised by the runtime).
  ClBuffer palette, out_positions, out_normals;
};

class OpenClCopyBackend final : public Backend {
 public:
  explicit OpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime)
      : runtime_(std::move(runtime)),
        info_(OpenClBackendInfo(*runtime_, "opencl",
                                "OpenCL kernel; palette written and result read back per "
                                "frame")) {}
  const BackendInfo& info() const override { return info_; }

  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    auto prepared = std::make_unique<OpenClPreparedMesh>(mesh);
    constexpr cl_mem_flags kCopyIn = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
    struct Plan {
      const char* what;
      ClBuffer* buffer;
      cl_mem_flags flags;
      std::size_t bytes;
      const void* host;
    };
    const std::size_t xyz_bytes = mesh->positions().size_bytes();
    std::vector<Plan> plan = {
        {"positions", &prepared->positions, kCopyIn, xyz_bytes, mesh->positions().data()},
        {"joints", &prepared->joints, kCopyIn, mesh->joints().size_bytes(), mesh->joints().data()},
        {"weights", &prepared->weights, kCopyIn, mesh->weights().size_bytes(),
         mesh->weights().data()},
        {"palette", &prepared->palette, CL_MEM_READ_ONLY,
         kFloatsPerJoint * sizeof(float) * mesh->joint_count(), nullptr},
        {"output positions", &prepared->out_positions, CL_MEM_WRITE_ONLY, xyz_bytes, nullptr}};
    if (mesh->has_normals()) {
      plan.push_back({"normals", &prepared->normals, kCopyIn, xyz_bytes, mesh->normals().data()});
      plan.push_back(
          {"output normals", &prepared->out_normals, CL_MEM_WRITE_ONLY, xyz_bytes, nullptr});
    }
    for (const Plan& p : plan) {
      auto buffer = runtime_->CreateBuffer(p.what, p.flags, p.bytes, p.host);
      if (!buffer.ok()) return buffer.status();
      *p.buffer = std::move(buffer).value();
    }
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }

  Status Skin(const PreparedMesh& base, const SkinFrame& frame) override {
    const auto& prepared = static_cast<const OpenClPreparedMesh&>(base);
    const bool with_normals = !frame.normals.empty();
    if (with_normals && prepared.out_normals.get() == nullptr) {
      return InvalidArgument("normals requested, but the mesh has none");
    }
    cl_command_queue queue = runtime_->queue();
    std::lock_guard lock(runtime_->mutex());
    // In-order queue: write, run, read happen in sequence and the last read blocks, so
    // the palette and outputs the caller passed are in use only within this call.
    if (cl_int err = clEnqueueWriteBuffer(queue, prepared.palette.get(), CL_FALSE, 0,
                                          frame.palette.size_bytes(), frame.palette.data(), 0,
                                          nullptr, nullptr);
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    SkinKernelArgs args{.palette = prepared.palette.get(),
                        .joints = prepared.joints.get(),
                        .weights = prepared.weights.get(),
                        .positions = prepared.positions.get(),
                        .out_positions = prepared.out_positions.get()};
    if (with_normals) {
      args.normals = prepared.normals.get();
      args.out_normals = prepared.out_normals.get();
    }
    if (Status s = runtime_->EnqueueSkin(prepared.mesh(), args); !s.ok()) {
      clFinish(queue);  // the palette write may still read the caller's memory
      return s;
    }
    if (with_normals) {
      if (cl_int err = clEnqueueReadBuffer(queue, prepared.out_normals.get(), CL_FALSE, 0,
                                           frame.normals.size_bytes(), frame.normals.data(), 0,
                                           nullptr, nullptr);
          err != CL_SUCCESS) {
        clFinish(queue);
        return ClError("clEnqueueReadBuffer(normals)", err);
      }
    }
    if (cl_int err = clEnqueueReadBuffer(queue, prepared.out_positions.get(), CL_TRUE, 0,
                                         frame.positions.size_bytes(), frame.positions.data(), 0,
                                         nullptr, nullptr);
        err != CL_SUCCESS) {
      clFinish(queue);
      return ClError("clEnqueueReadBuffer(positions)", err);
    }
    return Status::Ok();
  }

 private:
  std::shared_ptr<OpenClRuntime> runtime_;
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime) {
  return std::make_unique<OpenClCopyBackend>(std::move(runtime));
}

}  // namespace skinserve
