// Backend: one implementation of skinning (serial, openmp, sse, ...): linear blend
// skinning always, dual-quaternion skinning where info().methods lists it.
// A backend prepares each mesh once (its own layout, its own device buffers); per frame
// only the palette goes in and the vertices come out.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/engine/device_memory.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/model/status.h"

namespace skinserve {

struct BackendInfo {
  std::string id;           // stable id, the same on the wire, in the CLI and in reports
  std::string description;  // one line for humans
  bool available = true;
  std::string unavailable_reason;  // why not, when !available
  std::string device;              // e.g. the CPU model or the OpenCL device name
  int simd_width = 1;              // float lanes one instruction works on (1: scalar)
  std::string simd_target;         // SIMD target chosen at run time (`simd`), e.g. "AVX2"
  int threads = 1;                 // compute threads one frame occupies, at most
  // The fewest threads a frame can run on (SkinFrame::threads); 0: exactly `threads`.
  int min_threads = 0;
  std::vector<SkinningMethod> methods = {SkinningMethod::kLinear};  // what Skin() implements
  bool morph_targets = false;  // Skin() applies SkinFrame::morph_weights (else refuses them)
  bool tangents = false;       // Skin() writes SkinFrame::tangents (else refuses them)
  // Skin() reads a mesh's quantized rest stream itself (Mesh::quantized_rest()); other
  // backends skin the float values it decodes to.
  bool quantized_rest = false;
  // Encodings Skin() writes itself into SkinFrame::encoded (on the device, read back
  // encoded); for the others the caller encodes the float output (core/encoding).
  std::vector<VertexEncoding> encoded_outputs;
  // Writing snorm16 itself, Skin() keeps the frame's float positions on the host until it
  // has their box, in EncodedOutput::box_scratch when the caller gives one (simd).
  bool encoded_box_scratch = false;
  // SkinFrames skins frames with float32 output in host memory together too (not only
  // frames into device memory), cheaper than Skin on each: the engine then hands a tick's
  // such frames to it in chunks (Engine::SubmitGroup).
  bool skins_frames_together = false;

  bool Supports(SkinningMethod method) const;
  bool WritesEncoding(VertexEncoding encoding) const;
};

// A backend's resident copy of one mesh. Backends derive from it to hold their layout.
class PreparedMesh {
 public:
  explicit PreparedMesh(std::shared_ptr<const Mesh> mesh) : mesh_(std::move(mesh)) {}
  virtual ~PreparedMesh() = default;
  const Mesh& mesh() const { return *mesh_; }

 private:
  std::shared_ptr<const Mesh> mesh_;
};

// Device time of one frame, from a backend that runs on a device with profiling events
// (OpenCL); zero elsewhere.
struct DeviceTiming {
  int64_t transfer_ns = 0;  // host<->device copies, summed (they may overlap the kernels)
  int64_t kernel_ns = 0;    // kernels, summed
};

// A frame's output written encoded by the backend (BackendInfo::encoded_outputs) instead of
// as floats: exactly the bytes EncodePositions / EncodeNormals / EncodeTangents would make of
// the skinned floats (vertex_encoding.h), and for snorm16 the box of the skinned positions
// (ComputeBounds') in `bounds`. A value the encoding cannot hold fails the frame with the
// host encoder's error (naming the vertex). encoding kFloat32: not used.
struct EncodedOutput {
  VertexEncoding encoding = VertexEncoding::kFloat32;
  std::span<std::byte> positions;  // EncodedBytes(encoding, vertex_count)
  std::span<std::byte> normals;    // empty: no normals; else as positions
  std::span<std::byte> tangents;   // empty: no tangents; else EncodedTangentBytes
  Bounds* bounds = nullptr;        // snorm16: where the box goes; else unused
  // snorm16 on a backend with BackendInfo::encoded_box_scratch: empty, or 3 * vertex_count
  // floats (per instance) where it keeps the skinned positions until it has their box. The
  // caller's memory, so the caller can count it (the server's in-flight budget); empty: the
  // backend uses a buffer of its calling thread's.
  std::span<float> box_scratch;
  bool active() const { return encoding != VertexEncoding::kFloat32; }
};

// One frame of work, in the manner of ozz's SkinningJob: plain spans, Validate() first.
//  - palette:   12 * joint_count finite floats (see palette.h).
//  - positions: 3 * vertex_count floats written by the backend, x y z per vertex.
//  - normals:   empty to skip normals; else 3 * vertex_count floats, unit length, and
//               the mesh must have normals.
//  - tangents:  empty to skip tangents; else 4 * vertex_count floats, x y z w per vertex:
//               xyz skinned like the normal (the same upper 3x3, renormalised; for dual
//               quaternions rotated by the blended rotation), w the mesh's, copied. The
//               mesh must have tangents, and normals must be asked for too.
//  - threads:   the threads this frame may use, between info.min_threads and
//               info.threads (the engine's scheduler decides); 0: info.threads.
//  - device_timing: null, or where a device backend writes the frame's device time.
//  - method:    dual-quaternion also needs every joint matrix rigid (ValidateRigidPalette).
//  - morph_weights: the frame's active morph targets (ValidateMorphWeights); their deltas
//               are added to the rest positions, normals and tangents' xyz before
//               skinning, whatever the method. Empty (or all zero): the rest arrays as
//               they are.
//  - rest_positions, rest_normals, rest_tangents, rest_first: set by a backend's morph
//               stage only (morph_stage.h), for the loops: the rest arrays to skin, whose
//               index 0 is vertex rest_first (the first of the range being skinned); null
//               (and rest_first 0): the mesh's own.
struct SkinFrame {
  std::span<const float> palette;
  std::span<float> positions;
  std::span<float> normals;
  std::span<float> tangents;
  int threads = 0;
  DeviceTiming* device_timing = nullptr;
  SkinningMethod method = SkinningMethod::kLinear;
  std::span<const MorphWeight> morph_weights;
  const float* rest_positions = nullptr;
  const float* rest_normals = nullptr;
  const float* rest_tangents = nullptr;  // 4 floats per vertex like the mesh's
  std::size_t rest_first = 0;
  // Set: the backend writes these bytes instead of positions/normals/tangents, which are
  // then empty (the backend's info() lists encoded.encoding).
  EncodedOutput encoded;
  // Set: the backend writes float32 into this device memory it imported (device_memory.h)
  // instead of positions/normals/tangents, which are then empty.
  DeviceOutput device;

  bool wants_normals() const {
    return !normals.empty() || !encoded.normals.empty() || device.normals;
  }
  bool wants_tangents() const {
    return !tangents.empty() || !encoded.tangents.empty() || device.tangents;
  }
  Status Validate(const Mesh& mesh) const;

 private:
  Status ValidateEncoded(const Mesh& mesh) const;
};

// One instance's palette for `method`: ValidatePalette, and for dual quaternions
// ValidateRigidPalette. The one place both SkinFrame::Validate and the engine's checks
// (Engine::Submit) look at palette values.
Status ValidateFramePalette(std::span<const float> palette, SkinningMethod method,
                            uint32_t joint_count);
// The outputs a mesh can give: normals need the mesh's normals; tangents need the mesh's
// tangents and normals asked for too. INVALID_ARGUMENT saying which. Used by
// SkinFrame::Validate and by the engine's checks of a whole batch.
Status CheckOutputsAgainstMesh(bool normals, bool tangents, const Mesh& mesh);

// OK unless `weights` has a non-zero weight and the backend does not apply morph targets:
// then FAILED_PRECONDITION naming the backend and those that do. Backends without morph
// targets call it first in Skin(), so a frame's morphs are never dropped silently.
Status CheckMorphSupport(const BackendInfo& info, std::span<const MorphWeight> weights);

// The rest arrays a skinning loop reads for `frame`: the morph stage's, else the mesh's.
inline const float* RestPositions(const Mesh& mesh, const SkinFrame& frame) {
  return frame.rest_positions != nullptr ? frame.rest_positions : mesh.positions().data();
}
inline const float* RestNormals(const Mesh& mesh, const SkinFrame& frame) {
  return frame.rest_normals != nullptr ? frame.rest_normals : mesh.normals().data();
}
inline const float* RestTangents(const Mesh& mesh, const SkinFrame& frame) {
  return frame.rest_tangents != nullptr ? frame.rest_tangents : mesh.tangents().data();
}

// OK unless tangents are asked for and the backend does not skin them: then
// FAILED_PRECONDITION naming the backend and those that do.
Status CheckTangentSupport(const BackendInfo& info, bool tangents_requested);

class Backend {
 public:
  virtual ~Backend() = default;
  virtual const BackendInfo& info() const = 0;
  // Builds this backend's resident copy of `mesh`. Called once per mesh and backend.
  virtual Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh> mesh) = 0;
  // Skins one validated frame whose method info() lists (the engine checks before it
  // queues the frame; the CPU backends also refuse others with INVALID_ARGUMENT).
  // Thread-safe: may run concurrently, also on one mesh.
  virtual Status Skin(const PreparedMesh& prepared, const SkinFrame& frame) = 0;
  // Several frames skinned together: statuses[i] is frames[i]'s verdict (prepared[i] its
  // mesh). The engine hands over frames whose output is device memory (SkinFrame::device),
  // and with info().skins_frames_together float32 frames into host memory too. The default
  // runs Skin on each; `opencl` enqueues them on one queue and waits once for the device
  // frames, and for the host frames reads each back into pinned memory of the batch and
  // copies it out while the later ones still run, so that a tick's characters cost neither
  // a lane nor a wait each. Thread-safe like Skin.
  virtual void SkinFrames(std::span<const PreparedMesh* const> prepared,
                          std::span<const SkinFrame> frames, std::span<Status> statuses);
  // Imports device memory that frames then name in SkinFrame::device. The default:
  // FAILED_PRECONDITION saying this backend cannot (only `opencl` on a device with
  // cl_khr_external_memory_opaque_fd can).
  virtual Result<std::shared_ptr<DeviceMemory>> ImportDeviceMemory(
      const DeviceMemoryImport& import);
};

}  // namespace skinserve
