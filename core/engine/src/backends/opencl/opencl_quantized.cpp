#include "backends/opencl/opencl_quantized.h"

#include <fmt/format.h>

#include <utility>
#include <vector>

#include "backends/common/quantized_palette.h"
#include "backends/opencl/opencl_program.h"
#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {
namespace {

// The work-item shape of linear_blend_skinning.cl, whose macros the qskin_* kernels take:
// SKIN_VERTICES_PER_ITEM (the kernel checks it is 4) and one group per chunk alignment.
constexpr std::size_t kVerticesPerItem = 4;
constexpr std::size_t kItemsPerGroup = OpenClRuntime::kChunkAlignment / kVerticesPerItem;

bool Joints16(const QuantizedRest& rest) { return rest.joints8.empty(); }
bool Weights16(const QuantizedRest& rest) {
  return rest.encoding != RestEncoding::kQuantized8Weights;
}

}  // namespace

Result<QuantizedDeviceMesh> CreateQuantizedDeviceMesh(OpenClRuntime& runtime, const Mesh& mesh,
                                                      cl_mem_flags flags) {
  const QuantizedRest* rest = mesh.quantized_rest();
  if (rest == nullptr) return Internal("CreateQuantizedDeviceMesh: the mesh is not quantized");
  QuantizedDeviceMesh out;
  const cl_mem_flags in = CL_MEM_READ_ONLY | flags;
  auto make = [&](const char* what, ClBuffer* buffer, std::size_t bytes, const void* host) {
    // B = 1 has no weights, and OpenCL no empty buffers: a placeholder, never read.
    auto created = bytes == 0 ? runtime.CreateBuffer(what, CL_MEM_READ_ONLY, 4, nullptr)
                              : runtime.CreateBuffer(what, in, bytes, host);
    if (!created.ok()) return created.status();
    *buffer = std::move(created).value();
    return Status::Ok();
  };
  if (Status s = make("quantized positions", &out.positions, rest->positions.size() * 2,
                      rest->positions.data());
      !s.ok()) {
    return s;
  }
  const bool joints16 = Joints16(*rest);
  if (Status s = make("quantized joints", &out.joints,
                      joints16 ? rest->joints16.size() * 2 : rest->joints8.size(),
                      joints16 ? static_cast<const void*>(rest->joints16.data())
                               : static_cast<const void*>(rest->joints8.data()));
      !s.ok()) {
    return s;
  }
  const bool weights16 = Weights16(*rest);
  if (Status s = make("quantized weights", &out.weights,
                      weights16 ? rest->weights16.size() * 2 : rest->weights8.size(),
                      weights16 ? static_cast<const void*>(rest->weights16.data())
                                : static_cast<const void*>(rest->weights8.data()));
      !s.ok()) {
    return s;
  }
  if (!rest->normals.empty()) {
    if (Status s =
            make("quantized normals", &out.normals, rest->normals.size() * 2, rest->normals.data());
        !s.ok()) {
      return s;
    }
  }
  if (!rest->tangents.empty()) {
    if (Status s = make("quantized tangents", &out.tangents, rest->tangents.size() * 2,
                        rest->tangents.data());
        !s.ok()) {
      return s;
    }
  }
  return out;
}

Status PrepareQuantizedMesh(OpenClRuntime& runtime, const Mesh& mesh, cl_mem_flags flags,
                            ClBuffer* positions, ClBuffer* normals, ClBuffer* tangents,
                            ClBuffer* joints, ClBuffer* weights) {
  auto device_mesh = CreateQuantizedDeviceMesh(runtime, mesh, flags);
  if (!device_mesh.ok()) return device_mesh.status();
  if (Status s = runtime.quantized_kernels().Warm(runtime, mesh, *device_mesh); !s.ok()) return s;
  *positions = std::move(device_mesh->positions);
  *normals = std::move(device_mesh->normals);
  *tangents = std::move(device_mesh->tangents);
  *joints = std::move(device_mesh->joints);
  *weights = std::move(device_mesh->weights);
  return Status::Ok();
}

Status CheckQuantizedMethod(const std::string& backend_id, const Mesh& mesh,
                            SkinningMethod method) {
  if (method == SkinningMethod::kLinear) return Status::Ok();
  return FailedPrecondition(
      backend_id + ": mesh " + mesh.id() +
      " is stored with a quantized rest stream, which this backend skins with the linear "
      "method only; skin it linear, or on a backend that reads the float values it decodes to "
      "(serial, sse, ...), or upload it as float32");
}

std::span<const float> FoldedQuantizedPalette(std::span<const float> palette,
                                              const QuantizedRest& rest) {
  thread_local std::vector<float> buffer;
  buffer.resize(palette.size());
  for (std::size_t j = 0; j < palette.size() / 12; ++j) {
    FoldQuantizedBox(palette.data() + 12 * j, rest, buffer.data() + 12 * j);
  }
  return buffer;
}

OpenClQuantizedKernels::OpenClQuantizedKernels(cl_context context, cl_device_id device,
                                               std::string build_options, int local_tiles)
    : context_(context),
      device_(device),
      build_options_(std::move(build_options)),
      local_tiles_(local_tiles) {}

OpenClQuantizedKernels::~OpenClQuantizedKernels() {
  for (auto& [key, kernel] : kernels_) clReleaseKernel(kernel);
  for (auto& row : programs_) {
    for (cl_program program : row) {
      if (program != nullptr) clReleaseProgram(program);
    }
  }
}

Result<cl_program> OpenClQuantizedKernels::Program(bool joints16, bool weights16) {
  cl_program& program = programs_[joints16][weights16];
  if (program != nullptr) return program;
  const std::string options =
      fmt::format("{} -DQSKIN_JOINT={} -DQSKIN_WEIGHT={} -DQSKIN_WEIGHT_STEPS={}", build_options_,
                  joints16 ? "ushort" : "uchar", weights16 ? "ushort" : "uchar",
                  weights16 ? kWeightSteps16 : kWeightSteps8);
  const std::string_view sources[] = {kernels::kQuantizedSkinningSource};
  auto built = BuildSkinningProgram(context_, device_, sources, options, "quantized");
  if (!built.ok()) return built.status();
  program = *built;
  return program;
}

Result<cl_kernel> OpenClQuantizedKernels::Kernel(const OpenClLane& lane, const Mesh& mesh,
                                                 Outputs outputs, bool local) {
  const QuantizedRest& rest = *mesh.quantized_rest();
  const uint32_t b = mesh.influences();
  const auto key = std::make_tuple(&lane, Joints16(rest), Weights16(rest), b, outputs, local);
  std::lock_guard lock(mutex_);
  if (auto it = kernels_.find(key); it != kernels_.end()) return it->second;
  auto program = Program(Joints16(rest), Weights16(rest));
  if (!program.ok()) return program.status();
  const char* what = outputs == Outputs::kTangents  ? "_tangents"
                     : outputs == Outputs::kNormals ? "_normals"
                                                    : "";
  const std::string name = fmt::format("qskin{}{}_b{}", what, local ? "_local" : "", b);
  cl_int err = CL_SUCCESS;
  cl_kernel kernel = clCreateKernel(*program, name.c_str(), &err);
  if (err != CL_SUCCESS) return ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
  kernels_.emplace(key, kernel);
  return kernel;
}

Status OpenClQuantizedKernels::Warm(OpenClRuntime& runtime, const Mesh& mesh,
                                    const QuantizedDeviceMesh& device_mesh) {
  const std::vector<float> palette(12 * std::size_t{mesh.joint_count()}, 0.0f);
  constexpr cl_mem_flags kIn = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
  auto pal =
      runtime.CreateBuffer("warm palette", kIn, palette.size() * sizeof(float), palette.data());
  auto out = runtime.CreateBuffer("warm output", CL_MEM_WRITE_ONLY, 3 * sizeof(float), nullptr);
  auto out_n = runtime.CreateBuffer("warm output", CL_MEM_WRITE_ONLY, 3 * sizeof(float), nullptr);
  auto out_t = runtime.CreateBuffer("warm output", CL_MEM_WRITE_ONLY, 4 * sizeof(float), nullptr);
  for (const auto* r : {&pal, &out, &out_n, &out_t}) {
    if (!r->ok()) return r->status();
  }
  auto lane = runtime.AcquireLane();
  // One vertex of the mesh itself, each variant its frames may take.
  for (bool local : {false, true}) {
    if (local && !runtime.UsesLocalPalette(mesh, SkinningMethod::kLinear)) continue;
    for (Outputs outputs : {Outputs::kPositions, Outputs::kNormals, Outputs::kTangents}) {
      if (outputs != Outputs::kPositions && device_mesh.normals.get() == nullptr) continue;
      if (outputs == Outputs::kTangents && device_mesh.tangents.get() == nullptr) continue;
      SkinKernelArgs args{.palette = pal->get(),
                          .joints = device_mesh.joints.get(),
                          .weights = device_mesh.weights.get(),
                          .positions = device_mesh.positions.get(),
                          .out_positions = out->get()};
      if (outputs != Outputs::kPositions) {
        args.normals = device_mesh.normals.get();
        args.out_normals = out_n->get();
      }
      if (outputs == Outputs::kTangents) {
        args.tangents = device_mesh.tangents.get();
        args.out_tangents = out_t->get();
      }
      if (Status s = Enqueue(*lane, mesh, args, 0, 1, local, nullptr); !s.ok()) return s;
    }
  }
  if (cl_int err = clFinish(lane->compute); err != CL_SUCCESS) {
    return ClError("clFinish(quantized warm-up)", err);
  }
  return Status::Ok();
}

Status OpenClQuantizedKernels::Enqueue(OpenClLane& lane, const Mesh& mesh,
                                       const SkinKernelArgs& args, uint32_t first, uint32_t end,
                                       bool local, cl_event* event) {
  const QuantizedRest* rest = mesh.quantized_rest();
  if (rest == nullptr) return Internal("quantized kernel for a float mesh");
  if (args.method != SkinningMethod::kLinear) {
    return Internal("the quantized kernels blend linearly");
  }
  const uint32_t influences = mesh.influences();
  if (influences < 1 || influences > kMaxInfluences) {
    return Internal(fmt::format("no OpenCL kernel for {} influences", influences));
  }
  if (first % OpenClRuntime::kChunkAlignment != 0 || end > mesh.vertex_count() || first > end) {
    return Internal(
        fmt::format("bad vertex range [{}, {}) of {}", first, end, mesh.vertex_count()));
  }
  if (first == end) return Status::Ok();
  const bool with_normals = args.out_normals != nullptr;
  const bool with_tangents = args.out_tangents != nullptr;
  if (with_normals && args.normals == nullptr) {
    return Internal("output normals without input normals: the mesh has none");
  }
  if (with_tangents && (args.tangents == nullptr || !with_normals)) {
    return Internal("output tangents without input tangents or output normals");
  }
  auto kernel = Kernel(lane, mesh,
                       with_tangents  ? Outputs::kTangents
                       : with_normals ? Outputs::kNormals
                                      : Outputs::kPositions,
                       local);
  if (!kernel.ok()) return kernel.status();
  // Argument order: QSKIN_ARGS, QSKIN_NORMAL_ARGS, the tangents', SKIN_LOCAL_ARGS
  // (quantized_skinning.cl).
  cl_uint index = 0;
  cl_int err = CL_SUCCESS;
  auto set = [&](std::size_t size, const void* value) {
    if (err == CL_SUCCESS) err = clSetKernelArg(*kernel, index++, size, value);
  };
  for (const cl_mem* buffer :
       {&args.palette, &args.joints, &args.weights, &args.positions, &args.out_positions}) {
    set(sizeof(cl_mem), buffer);
  }
  // The range's end: the kernel clamps to end - 1 and never reads past it.
  const cl_uint count = end;
  set(sizeof(cl_uint), &count);
  if (with_normals) {
    // The folded palette's 3x3 carries the box's scale: the normal is divided by it.
    const cl_float4 normal_scale = {
        {1.0f / rest->scale[0], 1.0f / rest->scale[1], 1.0f / rest->scale[2], 0.0f}};
    set(sizeof(cl_mem), &args.normals);
    set(sizeof(cl_mem), &args.out_normals);
    set(sizeof(cl_float4), &normal_scale);
  }
  if (with_tangents) {
    set(sizeof(cl_mem), &args.tangents);
    set(sizeof(cl_mem), &args.out_tangents);
  }
  if (local) {
    const cl_uint floats = static_cast<cl_uint>(12 * std::size_t{mesh.joint_count()});
    set(floats * sizeof(float), nullptr);
    set(sizeof(cl_uint), &floats);
  }
  if (err != CL_SUCCESS) return ClError("clSetKernelArg(quantized)", err);
  const std::size_t offset = first / kVerticesPerItem;
  const std::size_t items = (end - first + kVerticesPerItem - 1) / kVerticesPerItem;
  const std::size_t group = kItemsPerGroup;
  const std::size_t per_group = local ? group * static_cast<std::size_t>(local_tiles_) : group;
  const std::size_t global = (items + per_group - 1) / per_group * group;
  if (err = clEnqueueNDRangeKernel(lane.compute, *kernel, 1, &offset, &global, &group, 0, nullptr,
                                   event);
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel(quantized)", err);
  }
  return Status::Ok();
}

}  // namespace skinserve
