#include "backends/opencl/opencl_encode.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string_view>

#include "backends/opencl/opencl_device_memory.h"
#include "backends/opencl/opencl_program.h"
#include "skinserve/kernels/embedded_kernels.h"

namespace skinserve {

std::vector<VertexEncoding> OpenClEncodedOutputs() {
  return {VertexEncoding::kFloat16, VertexEncoding::kSnorm16};
}

namespace {

constexpr std::size_t kGroup = 256;      // ENCODE_GROUP in encode_output.cl
constexpr std::size_t kMaxGroups = 256;  // the box's partial rows: at most 8 KiB to read back
constexpr std::size_t kRowFloats = 8;

std::size_t RoundUp(std::size_t n) { return (n + kGroup - 1) / kGroup * kGroup; }

Status SetArg(cl_kernel kernel, cl_uint index, std::size_t size, const void* value) {
  if (cl_int err = clSetKernelArg(kernel, index, size, value); err != CL_SUCCESS) {
    return ClError(fmt::format("clSetKernelArg(encode, {})", index).c_str(), err);
  }
  return Status::Ok();
}
// Per axis as core/encoding's AxesOf (vertex_encoding.cpp): centre, and 32767 / half-extent
// rounded once to float (0 for an empty axis); false when a scale overflows float.
bool Snorm16Axes(const Bounds& box, float centre[3], float scale[3]) {
  bool finite = true;
  for (int a = 0; a < 3; ++a) {
    centre[a] = box.min[a] * 0.5f + box.max[a] * 0.5f;
    const float half_extent = box.max[a] * 0.5f - box.min[a] * 0.5f;
    const double s = half_extent > 0 ? kSnorm16Max / static_cast<double>(half_extent) : 0.0;
    if (s > std::numeric_limits<float>::max()) finite = false;
    scale[a] = static_cast<float>(s);
  }
  return finite;
}

}  // namespace

struct OpenClEncoder::LaneState {
  cl_kernel bounds = nullptr, snorm16_positions = nullptr, snorm16_unit = nullptr, half = nullptr;
  ClBuffer partial, bad, positions, normals, tangents;
  std::size_t partial_bytes = 0, positions_bytes = 0, normals_bytes = 0, tangents_bytes = 0;
  PinnedBuffer pinned_positions, pinned_normals, pinned_tangents;
  std::vector<float> partial_rows;
  ~LaneState() {
    for (cl_kernel k : {bounds, snorm16_positions, snorm16_unit, half}) {
      if (k != nullptr) clReleaseKernel(k);
    }
  }
};

OpenClEncoder::OpenClEncoder(std::shared_ptr<OpenClRuntime> runtime)
    : runtime_(std::move(runtime)) {}

OpenClEncoder::~OpenClEncoder() {
  lanes_.clear();
  if (program_ != nullptr) clReleaseProgram(program_);
}

Status OpenClEncoder::Build() {
  const std::string_view sources[] = {kernels::kEncodeOutputSource};
  auto program =
      BuildClProgram(runtime_->context(), runtime_->device(), sources, "", "encode_output.cl");
  if (!program.ok()) return program.status();
  program_ = *program;
  return Warm();
}

// Runs every kernel once on one work-group of zeros: PoCL compiles a kernel for its
// work-group size at its first launch (tens of ms to seconds under load), which would
// otherwise land in the first frames that use each one.
Status OpenClEncoder::Warm() {
  cl_int err = CL_SUCCESS;
  cl_command_queue queue = clCreateCommandQueue(runtime_->context(), runtime_->device(), 0, &err);
  if (err != CL_SUCCESS) return ClError("clCreateCommandQueue(encode warm-up)", err);
  std::vector<float> zeros(4 * kGroup, 0.0f);
  auto in = runtime_->CreateBuffer("encode warm-up input", CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                                   zeros.size() * sizeof(float), zeros.data());
  auto out = runtime_->CreateBuffer("encode warm-up output", CL_MEM_READ_WRITE,
                                    zeros.size() * sizeof(float), nullptr);
  Status status = in.ok() ? out.status() : in.status();
  const cl_uint count = kGroup;
  const float zero = 0.0f;
  for (const char* name :
       {"bounds_partial", "encode_snorm16_positions", "encode_snorm16_unit", "encode_half"}) {
    if (!status.ok()) break;
    cl_kernel kernel = clCreateKernel(program_, name, &err);
    if (err != CL_SUCCESS) {
      status = ClError(fmt::format("clCreateKernel({})", name).c_str(), err);
      break;
    }
    cl_mem a = in->get(), b = out->get();
    const bool positions = std::string_view(name) == "encode_snorm16_positions";
    err = clSetKernelArg(kernel, 0, sizeof(cl_mem), &a);
    err |= clSetKernelArg(kernel, 1, sizeof(cl_uint), &count);
    if (positions) {
      for (cl_uint i = 2; i < 8; ++i) err |= clSetKernelArg(kernel, i, sizeof(float), &zero);
      err |= clSetKernelArg(kernel, 8, sizeof(cl_mem), &b);
    } else {
      err |= clSetKernelArg(kernel, 2, sizeof(cl_mem), &b);
      if (std::string_view(name) != "bounds_partial") {
        err |= clSetKernelArg(kernel, 3, sizeof(cl_mem), &b);  // the flag: any int of it
      }
    }
    const std::size_t global = kGroup, local = kGroup;
    if (err == CL_SUCCESS) {
      err = clEnqueueNDRangeKernel(queue, kernel, 1, nullptr, &global, &local, 0, nullptr, nullptr);
    }
    clReleaseKernel(kernel);
    if (err != CL_SUCCESS) status = ClError(fmt::format("encode warm-up ({})", name).c_str(), err);
  }
  if (cl_int finished = clFinish(queue); finished != CL_SUCCESS && status.ok()) {
    status = ClError("clFinish(encode warm-up)", finished);
  }
  clReleaseCommandQueue(queue);
  return status;
}

Result<OpenClEncoder::LaneState*> OpenClEncoder::StateOf(OpenClLane& lane) {
  std::lock_guard lock(mutex_);
  if (!built_) {
    build_status_ = Build();
    built_ = true;
  }
  if (!build_status_.ok()) return build_status_;
  auto& state = lanes_[&lane];
  if (state) return state.get();
  auto created = std::make_unique<LaneState>();
  struct Named {
    const char* name;
    cl_kernel* kernel;
  };
  for (const Named& k : {Named{"bounds_partial", &created->bounds},
                         Named{"encode_snorm16_positions", &created->snorm16_positions},
                         Named{"encode_snorm16_unit", &created->snorm16_unit},
                         Named{"encode_half", &created->half}}) {
    cl_int err = CL_SUCCESS;
    *k.kernel = clCreateKernel(program_, k.name, &err);
    if (err != CL_SUCCESS) return ClError(fmt::format("clCreateKernel({})", k.name).c_str(), err);
  }
  auto bad = runtime_->CreateBuffer("encode flag", CL_MEM_READ_WRITE, sizeof(cl_int), nullptr);
  if (!bad.ok()) return bad.status();
  created->bad = std::move(bad).value();
  state = std::move(created);
  return state.get();
}

namespace {

// Reads `count` floats of `buffer` back (blocking), for the host encoder's error path.
Result<std::vector<float>> ReadFloats(OpenClLane& lane, cl_mem buffer, std::size_t count) {
  std::vector<float> floats(count);
  if (count == 0) return floats;
  if (cl_int err = clEnqueueReadBuffer(lane.compute, buffer, CL_TRUE, 0, count * sizeof(float),
                                       floats.data(), 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueReadBuffer(floats to encode on the host)", err);
  }
  return floats;
}

// The host encoder on the device's floats: the frame's bytes when the device cannot encode
// it (a box too thin for a float scale), or, after the device refused a value, the host
// encoder's error naming it.
Status HostEncode(OpenClLane& lane, const SkinKernelArgs& floats, uint32_t vertex_count,
                  const SkinFrame& frame) {
  const EncodedOutput& enc = frame.encoded;
  auto positions = ReadFloats(lane, floats.out_positions, 3ull * vertex_count);
  if (!positions.ok()) return positions.status();
  Bounds box;
  if (QuantizedToBox(enc.encoding)) {
    Result<Bounds> computed = ComputeBounds(*positions);
    if (!computed.ok()) return computed.status();
    box = *computed;
    *enc.bounds = box;
  }
  if (Status s = EncodePositions(enc.encoding, *positions, box, enc.positions); !s.ok()) return s;
  if (!enc.normals.empty()) {
    auto normals = ReadFloats(lane, floats.out_normals, 3ull * vertex_count);
    if (!normals.ok()) return normals.status();
    if (Status s = EncodeNormals(enc.encoding, *normals, enc.normals); !s.ok()) return s;
  }
  if (!enc.tangents.empty()) {
    auto tangents = ReadFloats(lane, floats.out_tangents, 4ull * vertex_count);
    if (!tangents.ok()) return tangents.status();
    if (Status s = EncodeTangents(enc.encoding, *tangents, enc.tangents); !s.ok()) return s;
  }
  return Status::Ok();
}

// HostEncode for a frame whose output is device memory: the host encoder's bytes, then
// written into the memory at the frame's offsets.
Status HostEncodeIntoDevice(OpenClLane& lane, const SkinKernelArgs& floats, uint32_t vertex_count,
                            const SkinFrame& frame, ClEvents& transfers) {
  const DeviceOutput& device = frame.device;
  const std::size_t bytes = EncodedBytes(device.encoding, vertex_count);
  std::vector<std::byte> positions(bytes), normals(device.normals ? bytes : 0),
      tangents(device.tangents ? EncodedTangentBytes(device.encoding, vertex_count) : 0);
  SkinFrame host = frame;
  host.device = {};
  host.encoded = {.encoding = device.encoding,
                  .positions = positions,
                  .normals = normals,
                  .tangents = tangents,
                  .bounds = device.bounds};
  if (Status s = HostEncode(lane, floats, vertex_count, host); !s.ok()) return s;
  std::vector<DeviceOutputPiece> pieces = {{"clEnqueueWriteBuffer(encoded positions)", nullptr,
                                            positions.data(), device.positions_offset, bytes}};
  if (device.normals) {
    pieces.push_back({"clEnqueueWriteBuffer(encoded normals)", nullptr, normals.data(),
                      device.normals_offset, bytes});
  }
  if (device.tangents) {
    pieces.push_back({"clEnqueueWriteBuffer(encoded tangents)", nullptr, tangents.data(),
                      device.tangents_offset, tangents.size()});
  }
  return WriteDevicePieces(lane, frame, pieces, transfers);  // waits: the vectors outlive it
}

Status Enqueue(OpenClLane& lane, cl_kernel kernel, std::size_t count, const char* what,
               ClEvents& kernels) {
  const std::size_t global = RoundUp(std::max<std::size_t>(count, 1)), local = kGroup;
  if (cl_int err = clEnqueueNDRangeKernel(lane.compute, kernel, 1, nullptr, &global, &local, 0,
                                          nullptr, kernels.Next());
      err != CL_SUCCESS) {
    return ClError(fmt::format("clEnqueueNDRangeKernel({})", what).c_str(), err);
  }
  return Status::Ok();
}

}  // namespace

// One array of the encoded output: where its floats are on the device (`in`, then, once
// its kernel is enqueued, its bytes), where they go, and the lane's buffers for them.
struct OpenClEncoder::EncodedArray {
  const char* what;
  cl_mem in;
  std::span<std::byte> to;  // host memory (empty for device memory)
  std::size_t bytes;        // the encoded array's
  uint64_t device_offset;   // device memory: where it goes
  std::size_t values;
  bool positions;
  ClBuffer* buffer;
  std::size_t* capacity;
  PinnedBuffer* pinned;
};

Status OpenClEncoder::Encode(OpenClLane& lane, const SkinKernelArgs& floats, uint32_t vertex_count,
                             const SkinFrame& frame, bool zero_copy, ClEvents& kernels,
                             ClEvents& transfers) {
  const EncodedOutput& enc = frame.encoded;
  const bool snorm16 = enc.encoding == VertexEncoding::kSnorm16;
  Result<LaneState*> found = StateFor(lane, enc.encoding);
  if (!found.ok()) return found.status();
  LaneState& state = **found;
  Snorm16Box box;
  Result<bool> on_device = PrepareEncode(lane, state, floats, vertex_count, enc.encoding,
                                         enc.bounds, &box, kernels, transfers);
  if (!on_device.ok()) return on_device.status();
  if (!*on_device) return HostEncode(lane, floats, vertex_count, frame);
  std::vector<EncodedArray> arrays = EncodedArrays(state, floats, enc, vertex_count);
  std::vector<ClBuffer> wrapped;  // zero copy: this frame's buffers around the caller's memory
  if (Status s = EnqueueEncodeKernels(lane, state, snorm16 ? &box : nullptr, zero_copy, arrays,
                                      &wrapped, kernels);
      !s.ok()) {
    return s;
  }
  if (Status s = EnqueueReadBack(lane, zero_copy, arrays, transfers); !s.ok()) return s;
  // The flag last, in order on the compute queue: the one wait.
  if (Status s =
          CheckFlag(lane, state, [&] { return HostEncode(lane, floats, vertex_count, frame); });
      !s.ok()) {
    return s;
  }
  if (!zero_copy && runtime_->staging()) {
    for (const EncodedArray& a : arrays) std::memcpy(a.to.data(), a.pinned->host, a.to.size());
  }
  return Status::Ok();
}

Status OpenClEncoder::EncodeIntoDevice(OpenClLane& lane, const SkinKernelArgs& floats,
                                       uint32_t vertex_count, const SkinFrame& frame,
                                       ClEvents& kernels, ClEvents& transfers) {
  const DeviceOutput& device = frame.device;
  Result<LaneState*> found = StateFor(lane, device.encoding);
  if (!found.ok()) return found.status();
  LaneState& state = **found;
  Snorm16Box box;
  Result<bool> on_device = PrepareEncode(lane, state, floats, vertex_count, device.encoding,
                                         device.bounds, &box, kernels, transfers);
  if (!on_device.ok()) return on_device.status();
  if (!*on_device) return HostEncodeIntoDevice(lane, floats, vertex_count, frame, transfers);
  std::vector<EncodedArray> arrays = DeviceArrays(state, floats, device, vertex_count);
  std::vector<ClBuffer> unused;  // device arrays go to the lane's buffers, never wrapped
  if (Status s = EnqueueEncodeKernels(lane, state,
                                      device.encoding == VertexEncoding::kSnorm16 ? &box : nullptr,
                                      /*zero_copy=*/false, arrays, &unused, kernels);
      !s.ok()) {
    return s;
  }
  // The flag before anything is copied: a refused value leaves the memory as it was.
  if (Status s = CheckFlag(
          lane, state,
          [&] { return HostEncodeIntoDevice(lane, floats, vertex_count, frame, transfers); });
      !s.ok()) {
    return s;
  }
  std::vector<DeviceOutputPiece> pieces;
  for (const EncodedArray& a : arrays) {
    pieces.push_back({a.what, a.in, nullptr, a.device_offset, a.bytes});
  }
  return WriteDevicePieces(lane, frame, pieces, transfers);
}

Result<OpenClEncoder::LaneState*> OpenClEncoder::StateFor(OpenClLane& lane,
                                                          VertexEncoding encoding) {
  if (encoding != VertexEncoding::kSnorm16 && encoding != VertexEncoding::kFloat16) {
    return InvalidArgument(
        fmt::format("the OpenCL backends do not write {} output", VertexEncodingName(encoding)));
  }
  return StateOf(lane);
}

Status OpenClEncoder::CheckFlag(OpenClLane& lane, LaneState& state,
                                const std::function<Status()>& host_encode) {
  cl_int refused = 0;
  if (cl_int err = clEnqueueReadBuffer(lane.compute, state.bad.get(), CL_TRUE, 0, sizeof(refused),
                                       &refused, 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueReadBuffer(encode flag)", err);
  }
  if (refused == 0) return Status::Ok();
  Status s = host_encode();
  return s.ok() ? Internal("the device refused a value to encode that the host encoder takes") : s;
}

Result<bool> OpenClEncoder::PrepareEncode(OpenClLane& lane, LaneState& state,
                                          const SkinKernelArgs& floats, uint32_t vertex_count,
                                          VertexEncoding encoding, Bounds* bounds, Snorm16Box* box,
                                          ClEvents& kernels, ClEvents& transfers) {
  const cl_int zero = 0;
  if (cl_int err = clEnqueueFillBuffer(lane.compute, state.bad.get(), &zero, sizeof(zero), 0,
                                       sizeof(zero), 0, nullptr, nullptr);
      err != CL_SUCCESS) {
    return ClError("clEnqueueFillBuffer(encode flag)", err);
  }
  if (encoding != VertexEncoding::kSnorm16) return true;
  auto device_box = DeviceBox(lane, state, floats.out_positions, vertex_count, kernels, transfers);
  if (!device_box.ok()) return device_box.status();
  // Not finite (the host's error names the vertex), or an axis too thin for a float scale
  // (the host encoder works in double): the host encoder takes the frame.
  if (!device_box->has_value() || !Snorm16Axes(**device_box, box->centre, box->scale)) {
    return false;
  }
  *bounds = **device_box;
  return true;
}

Result<std::optional<Bounds>> OpenClEncoder::DeviceBox(OpenClLane& lane, LaneState& state,
                                                       cl_mem positions, uint32_t vertex_count,
                                                       ClEvents& kernels, ClEvents& transfers) {
  const std::size_t groups =
      std::clamp<std::size_t>((vertex_count + kGroup - 1) / kGroup, 1, kMaxGroups);
  const std::size_t row_bytes = groups * kRowFloats * sizeof(float);
  if (Status s = runtime_->GrowBuffer("encode box rows", CL_MEM_READ_WRITE, row_bytes,
                                      &state.partial, &state.partial_bytes);
      !s.ok()) {
    return s;
  }
  cl_mem partial = state.partial.get();
  const cl_uint vertices = vertex_count;
  if (Status s = SetArg(state.bounds, 0, sizeof(cl_mem), &positions); !s.ok()) return s;
  if (Status s = SetArg(state.bounds, 1, sizeof(cl_uint), &vertices); !s.ok()) return s;
  if (Status s = SetArg(state.bounds, 2, sizeof(cl_mem), &partial); !s.ok()) return s;
  const std::size_t global = groups * kGroup, local = kGroup;
  if (cl_int err = clEnqueueNDRangeKernel(lane.compute, state.bounds, 1, nullptr, &global, &local,
                                          0, nullptr, kernels.Next());
      err != CL_SUCCESS) {
    return ClError("clEnqueueNDRangeKernel(bounds_partial)", err);
  }
  state.partial_rows.resize(groups * kRowFloats);
  if (cl_int err = clEnqueueReadBuffer(lane.compute, partial, CL_TRUE, 0, row_bytes,
                                       state.partial_rows.data(), 0, nullptr, transfers.Next());
      err != CL_SUCCESS) {
    return ClError("clEnqueueReadBuffer(encode box rows)", err);
  }
  Bounds box;
  bool finite = true;
  for (std::size_t g = 0; g < groups; ++g) {
    const float* row = &state.partial_rows[g * kRowFloats];
    for (int a = 0; a < 3; ++a) {
      box.min[a] = g == 0 ? row[a] : std::fmin(box.min[a], row[a]);
      box.max[a] = g == 0 ? row[3 + a] : std::fmax(box.max[a], row[3 + a]);
    }
    finite = finite && row[6] == 0.0f;
  }
  if (!finite) return std::optional<Bounds>();
  return std::optional<Bounds>(box);
}

std::vector<OpenClEncoder::EncodedArray> OpenClEncoder::EncodedArrays(LaneState& state,
                                                                      const SkinKernelArgs& floats,
                                                                      const EncodedOutput& enc,
                                                                      uint32_t vertex_count) {
  std::vector<EncodedArray> arrays = {{"encoded positions", floats.out_positions, enc.positions,
                                       enc.positions.size(), 0, 3ull * vertex_count, true,
                                       &state.positions, &state.positions_bytes,
                                       &state.pinned_positions}};
  if (!enc.normals.empty()) {
    arrays.push_back({"encoded normals", floats.out_normals, enc.normals, enc.normals.size(), 0,
                      3ull * vertex_count, false, &state.normals, &state.normals_bytes,
                      &state.pinned_normals});
  }
  if (!enc.tangents.empty()) {
    arrays.push_back({"encoded tangents", floats.out_tangents, enc.tangents, enc.tangents.size(), 0,
                      4ull * vertex_count, false, &state.tangents, &state.tangents_bytes,
                      &state.pinned_tangents});
  }
  return arrays;
}

std::vector<OpenClEncoder::EncodedArray> OpenClEncoder::DeviceArrays(LaneState& state,
                                                                     const SkinKernelArgs& floats,
                                                                     const DeviceOutput& device,
                                                                     uint32_t vertex_count) {
  const std::size_t bytes = EncodedBytes(device.encoding, vertex_count);
  std::vector<EncodedArray> arrays = {{"clEnqueueCopyBuffer(encoded positions)",
                                       floats.out_positions,
                                       {},
                                       bytes,
                                       device.positions_offset,
                                       3ull * vertex_count,
                                       true,
                                       &state.positions,
                                       &state.positions_bytes,
                                       &state.pinned_positions}};
  if (device.normals) {
    arrays.push_back({"clEnqueueCopyBuffer(encoded normals)",
                      floats.out_normals,
                      {},
                      bytes,
                      device.normals_offset,
                      3ull * vertex_count,
                      false,
                      &state.normals,
                      &state.normals_bytes,
                      &state.pinned_normals});
  }
  if (device.tangents) {
    arrays.push_back({"clEnqueueCopyBuffer(encoded tangents)",
                      floats.out_tangents,
                      {},
                      EncodedTangentBytes(device.encoding, vertex_count),
                      device.tangents_offset,
                      4ull * vertex_count,
                      false,
                      &state.tangents,
                      &state.tangents_bytes,
                      &state.pinned_tangents});
  }
  return arrays;
}

Status OpenClEncoder::EnqueueEncodeKernels(OpenClLane& lane, LaneState& state,
                                           const Snorm16Box* box, bool zero_copy,
                                           std::vector<EncodedArray>& arrays,
                                           std::vector<ClBuffer>* wrapped, ClEvents& kernels) {
  wrapped->reserve(arrays.size());
  cl_mem bad = state.bad.get();
  for (EncodedArray& out : arrays) {
    cl_mem target = nullptr;
    if (zero_copy) {
      auto created = runtime_->CreateBuffer(out.what, CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                            out.to.size(), out.to.data());
      if (!created.ok()) return created.status();
      target = wrapped->emplace_back(std::move(created).value()).get();
    } else {
      if (Status s = runtime_->GrowBuffer(out.what, CL_MEM_READ_WRITE, out.bytes, out.buffer,
                                          out.capacity);
          !s.ok()) {
        return s;
      }
      target = out.buffer->get();
    }
    const cl_uint count = static_cast<cl_uint>(out.values);
    cl_kernel kernel = box == nullptr  ? state.half
                       : out.positions ? state.snorm16_positions
                                       : state.snorm16_unit;
    if (Status s = SetArg(kernel, 0, sizeof(cl_mem), &out.in); !s.ok()) return s;
    if (Status s = SetArg(kernel, 1, sizeof(cl_uint), &count); !s.ok()) return s;
    if (box != nullptr && out.positions) {
      for (int a = 0; a < 3; ++a) {
        if (Status s = SetArg(kernel, 2 + a, sizeof(float), &box->centre[a]); !s.ok()) return s;
        if (Status s = SetArg(kernel, 5 + a, sizeof(float), &box->scale[a]); !s.ok()) return s;
      }
      if (Status s = SetArg(kernel, 8, sizeof(cl_mem), &target); !s.ok()) return s;
    } else {
      if (Status s = SetArg(kernel, 2, sizeof(cl_mem), &target); !s.ok()) return s;
      if (Status s = SetArg(kernel, 3, sizeof(cl_mem), &bad); !s.ok()) return s;
    }
    if (Status s = Enqueue(lane, kernel, out.values, out.what, kernels); !s.ok()) return s;
    out.in = target;  // from here on: where the bytes are on the device
  }
  return Status::Ok();
}

Status OpenClEncoder::EnqueueReadBack(OpenClLane& lane, bool zero_copy,
                                      std::vector<EncodedArray>& arrays, ClEvents& transfers) {
  for (EncodedArray& out : arrays) {
    if (zero_copy) {
      cl_int err = CL_SUCCESS;
      void* mapped = clEnqueueMapBuffer(lane.compute, out.in, CL_FALSE, CL_MAP_READ, 0,
                                        out.to.size(), 0, nullptr, transfers.Next(), &err);
      if (err != CL_SUCCESS) return ClError("clEnqueueMapBuffer(encoded output)", err);
      err = clEnqueueUnmapMemObject(lane.compute, out.in, mapped, 0, nullptr, nullptr);
      if (err != CL_SUCCESS) return ClError("clEnqueueUnmapMemObject(encoded output)", err);
      continue;
    }
    void* to = out.to.data();
    if (runtime_->staging()) {
      if (Status s = runtime_->GrowPinned(lane.compute, out.what, out.to.size(), out.pinned);
          !s.ok()) {
        return s;
      }
      to = out.pinned->host;
    }
    if (cl_int err = clEnqueueReadBuffer(lane.compute, out.in, CL_FALSE, 0, out.to.size(), to, 0,
                                         nullptr, transfers.Next());
        err != CL_SUCCESS) {
      return ClError("clEnqueueReadBuffer(encoded output)", err);
    }
  }
  return Status::Ok();
}

}  // namespace skinserve
