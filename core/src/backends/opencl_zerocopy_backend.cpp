// `opencl-zerocopy`: stands for the paper's OpenCL-OpenGL interop, where the data never
// leaves the buffers the renderer uses. Every buffer wraps host memory in place
// (CL_MEM_USE_HOST_PTR): the mesh's own aligned arrays, the frame's palette and the
// caller's output. On a CPU device PoCL runs the kernel on that memory, so there is no
// write before and no read after; mapping the outputs is only the synchronisation the
// OpenCL memory model asks for.
#include "opencl_backends.h"

namespace skinserve {
namespace {

struct ZeroCopyPreparedMesh final : PreparedMesh {
  using PreparedMesh::PreparedMesh;
  ClBuffer positions, normals, joints, weights;
};

class OpenClZeroCopyBackend final : public Backend {
 public:
  explicit OpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime)
      : runtime_(std::move(runtime)),
        info_(OpenClBackendInfo(*runtime_, "opencl-zerocopy",
                                "OpenCL kernel on host memory in place, no copies")) {}
  const BackendInfo& info() const override { return info_; }

  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) override {
    // The prepared mesh holds the Mesh alive, and with it the memory these buffers wrap.
    auto prepared = std::make_unique<ZeroCopyPreparedMesh>(mesh);
    auto wrap = [&](ClBuffer* buffer, auto span) -> Status {
      auto created = runtime_->CreateBuffer(CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                            span.size_bytes(), span.data());
      if (!created.ok()) return created.status();
      *buffer = std::move(created).value();
      return Status::Ok();
    };
    for (Status s :
         {wrap(&prepared->positions, mesh->positions()), wrap(&prepared->joints, mesh->joints()),
          wrap(&prepared->weights, mesh->weights())}) {
      if (!s.ok()) return s;
    }
    if (mesh->has_normals()) {
      if (Status s = wrap(&prepared->normals, mesh->normals()); !s.ok()) return s;
    }
    return std::unique_ptr<PreparedMesh>(std::move(prepared));
  }

  Status Skin(const PreparedMesh& base, const SkinFrame& frame) override {
    const auto& prepared = static_cast<const ZeroCopyPreparedMesh&>(base);
    const bool with_normals = !frame.normals.empty();
    std::lock_guard lock(runtime_->mutex());
    auto palette = runtime_->CreateBuffer(CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                          frame.palette.size_bytes(), frame.palette.data());
    if (!palette.ok()) return palette.status();
    auto out_positions =
        runtime_->CreateBuffer(CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                               frame.positions.size_bytes(), frame.positions.data());
    if (!out_positions.ok()) return out_positions.status();
    ClBuffer out_normals;
    if (with_normals) {
      auto created = runtime_->CreateBuffer(CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                            frame.normals.size_bytes(), frame.normals.data());
      if (!created.ok()) return created.status();
      out_normals = std::move(created).value();
    }
    const SkinKernelArgs args{palette->get(),         prepared.positions.get(),
                              prepared.normals.get(), prepared.joints.get(),
                              prepared.weights.get(), out_positions->get(),
                              out_normals.get()};
    if (Status s = runtime_->EnqueueSkin(prepared.mesh(), args, with_normals); !s.ok()) {
      return s;
    }
    for (const ClBuffer* out : {&*out_positions, &out_normals}) {
      if (out->get() == nullptr) continue;
      if (Status s = SyncToHost(*out, frame.positions.size_bytes()); !s.ok()) return s;
    }
    // One wait for the whole in-order sequence: kernel, map, unmap.
    if (cl_int err = clFinish(runtime_->queue()); err != CL_SUCCESS) {
      return ClError("clFinish", err);
    }
    return Status::Ok();
  }

 private:
  // Enqueues a map and an unmap: they make the kernel's writes visible in the host memory
  // the buffer wraps (nothing to do on PoCL's CPU device, a copy on a device with memory
  // of its own). Non-blocking: the in-order queue orders them after the kernel, and the
  // caller's clFinish is the one wait (a blocking map would be a second one).
  Status SyncToHost(const ClBuffer& buffer, std::size_t bytes) {
    cl_int err = CL_SUCCESS;
    void* mapped = clEnqueueMapBuffer(runtime_->queue(), buffer.get(), CL_FALSE, CL_MAP_READ, 0,
                                      bytes, 0, nullptr, nullptr, &err);
    if (err != CL_SUCCESS) return ClError("clEnqueueMapBuffer", err);
    err = clEnqueueUnmapMemObject(runtime_->queue(), buffer.get(), mapped, 0, nullptr, nullptr);
    if (err != CL_SUCCESS) return ClError("clEnqueueUnmapMemObject", err);
    return Status::Ok();
  }

  std::shared_ptr<OpenClRuntime> runtime_;
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime) {
  return std::make_unique<OpenClZeroCopyBackend>(std::move(runtime));
}

}  // namespace skinserve
