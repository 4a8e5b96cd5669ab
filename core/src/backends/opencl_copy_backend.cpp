// `opencl`: the paper's plain OpenCL path. The mesh is copied into device buffers once;
// each frame writes the palette to the device and reads the result back.
#include "opencl_backends.h"

namespace skinserve {
namespace {

struct OpenClPreparedMesh final : PreparedMesh {
  using PreparedMesh::PreparedMesh;
  ClBuffer positions, normals, joints, weights;
  ClBuffer palette, out_positions, out_normals;  // per-frame traffic, reused
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
      ClBuffer* buffer;
      cl_mem_flags flags;
      std::size_t bytes;
      const void* host;
    };
    const std::size_t xyz_bytes = mesh->positions().size_bytes();
    std::vector<Plan> plan = {
        {&prepared->positions, kCopyIn, xyz_bytes, mesh->positions().data()},
        {&prepared->joints, kCopyIn, mesh->joints().size_bytes(), mesh->joints().data()},
        {&prepared->weights, kCopyIn, mesh->weights().size_bytes(), mesh->weights().data()},
        {&prepared->palette, CL_MEM_READ_ONLY, 48ull * mesh->joint_count(), nullptr},
        {&prepared->out_positions, CL_MEM_WRITE_ONLY, xyz_bytes, nullptr}};
    if (mesh->has_normals()) {
      plan.push_back({&prepared->normals, kCopyIn, xyz_bytes, mesh->normals().data()});
      plan.push_back({&prepared->out_normals, CL_MEM_WRITE_ONLY, xyz_bytes, nullptr});
    }
    for (const Plan& p : plan) {
      auto buffer = runtime_->CreateBuffer(p.flags, p.bytes, p.host);
      if (!buffer.ok()) return buffer.status();
      *p.buffer = std::move(buffer).value();
    }
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }

  Status Skin(const PreparedMesh& base, const SkinFrame& frame) override {
    const auto& prepared = static_cast<const OpenClPreparedMesh&>(base);
    const Mesh& mesh = prepared.mesh();
    const bool with_normals = !frame.normals.empty();
    cl_command_queue queue = runtime_->queue();
    std::lock_guard lock(runtime_->mutex());
    // In-order queue: write, run, read happen in sequence; the last read blocks.
    if (cl_int err = clEnqueueWriteBuffer(queue, prepared.palette.get(), CL_FALSE, 0,
                                          frame.palette.size_bytes(), frame.palette.data(), 0,
                                          nullptr, nullptr);
        err != CL_SUCCESS) {
      return ClError("clEnqueueWriteBuffer(palette)", err);
    }
    const SkinKernelArgs args{prepared.palette.get(),    prepared.positions.get(),
                              prepared.normals.get(),    prepared.joints.get(),
                              prepared.weights.get(),    prepared.out_positions.get(),
                              prepared.out_normals.get()};
    if (Status s = runtime_->EnqueueSkin(mesh, args, with_normals); !s.ok()) return s;
    if (with_normals) {
      if (cl_int err = clEnqueueReadBuffer(queue, prepared.out_normals.get(), CL_FALSE, 0,
                                           frame.normals.size_bytes(), frame.normals.data(), 0,
                                           nullptr, nullptr);
          err != CL_SUCCESS) {
        return ClError("clEnqueueReadBuffer(normals)", err);
      }
    }
    if (cl_int err = clEnqueueReadBuffer(queue, prepared.out_positions.get(), CL_TRUE, 0,
                                         frame.positions.size_bytes(), frame.positions.data(), 0,
                                         nullptr, nullptr);
        err != CL_SUCCESS) {
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
