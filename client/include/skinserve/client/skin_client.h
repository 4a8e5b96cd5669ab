// SkinClient: the C++ client library of skinserve.v1.Skinning. It uploads meshes in
// chunks (skipping content the server already has), skins single frames, and remembers
// what it uploaded so that a server answering NOT_FOUND (restarted, or a new replica)
// gets the mesh again transparently.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/client/lost_upload.h"
#include "skinserve/client/pose.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.grpc.pb.h"
#include "skinserve/wire/conversions.h"
#include "skinserve/wire/raw_part.h"

namespace skinserve::client {

using wire::RawPart;

class Tick;  // skinserve/client/tick.h
struct TickResult;

inline constexpr std::size_t kUploadChunkBytes = 1 << 20;
// The most vertices (instances x vertices per instance) the client accepts in one frame.
inline constexpr uint64_t kMaxFrameVertices = uint64_t{1} << 28;

// One frame as the server returned it, reassembled from its parts and decoded to float32.
// Meant to be reused from frame to frame: its vectors keep their capacity, so a steady
// stream of frames of one shape allocates nothing here.
struct FrameResult {
  uint64_t frame = 0;
  Status status;           // the frame's own error, if it failed (then the arrays are empty)
  uint32_t vertices = 0;   // per instance
  uint32_t instances = 0;  // vertex sets held (1 for a single instance)
  VertexEncoding encoding = VertexEncoding::kFloat32;  // how the server sent them
  std::vector<float> positions;  // x y z, instance after instance: 3 * vertices each
  std::vector<float> normals;    // as positions, or empty when not asked for
  // x y z w, instance after instance: 4 * vertices each (SkinOptions::want_tangents; w is
  // exactly +1 or -1), or empty when not asked for.
  std::vector<float> tangents;
  std::vector<Bounds> bounds;  // per instance: the box snorm16 positions were quantized to
  v1::ServerTiming timing;
  // A frame written into a shared-memory region (SkinOptions::output): `positions` and
  // `normals` (and `tangents`) stay empty and these view the region instead, every instance
  // back to back, in `encoding` (no copy; valid until the region's bytes are written
  // again). DecodeRegionFrame decodes them into `positions`, `normals` and `tangents`.
  std::span<const std::byte> region_positions;
  std::span<const std::byte> region_normals;
  std::span<const std::byte> region_tangents;  // 4 values a vertex

  bool in_region() const { return !region_positions.empty(); }
  // float32 frames in a region: one instance's positions or normals, read in place.
  std::span<const float> region_floats(bool of_normals, uint32_t instance) const {
    const std::span<const std::byte> bytes = of_normals ? region_normals : region_positions;
    const std::size_t count = 3ull * vertices;
    if (encoding != VertexEncoding::kFloat32 || bytes.size() < (instance + 1ull) * count * 4) {
      return {};
    }
    return {reinterpret_cast<const float*>(bytes.data()) + count * instance, count};
  }

  std::span<const float> instance_positions(uint32_t instance) const {
    return std::span<const float>(positions).subspan(3ull * vertices * instance, 3ull * vertices);
  }
  std::span<const float> instance_normals(uint32_t instance) const {
    if (normals.empty()) return {};
    return std::span<const float>(normals).subspan(3ull * vertices * instance, 3ull * vertices);
  }
  std::span<const float> instance_tangents(uint32_t instance) const {
    if (tangents.empty()) return {};
    return std::span<const float>(tangents).subspan(4ull * vertices * instance, 4ull * vertices);
  }
};

// Where the server writes a frame on the same host (the same-host data plane,
// docs/serving/shared-memory.md): a region this process mapped and registered.
struct RegionOutput {
  std::string name;                            // as registered (SkinClient::RegisterRegion)
  const SharedMemoryRegion* region = nullptr;  // this process's mapping of it; null: off
  uint64_t offset = 0;                         // a multiple of wire::kRegionAlignment
  // StreamFrames: each frame in flight has its own slot, the i-th at offset + i * stride
  // (wire::RegionFrameBytes of the frame's shape, or more); the region must hold `window`.
  uint64_t stride = 0;
  bool enabled() const { return region != nullptr; }
};

// Decodes a frame written into a region (FrameResult::in_region) into its `positions` and
// `normals` (and `tangents`), as a frame sent over gRPC arrives; other frames are left as
// they are.
Status DecodeRegionFrame(FrameResult* result);

// Gathers a frame's parts into a FrameResult, decoding each part's encoding; true once
// the part with `last` has arrived. Parts must come as the contract says: instance by
// instance, each in vertex order, ranges inside the frame (or, packed, several whole
// instances per part: SkinRequest.pack_instances), every part of one frame with
// the same shape and encoding (and the same box within an instance). Anything else sets
// result->status (INTERNAL, naming the frame, the instance and the range). Use a fresh
// assembler per frame (it allocates nothing); the result may be reused.
class FrameAssembler {
 public:
  // `output`: the region the frame named, if any (it must outlive the assembler).
  explicit FrameAssembler(const RegionOutput* output = nullptr) : output_(output) {}
  bool Add(const v1::SkinResponse& part, FrameResult* result);
  // The same from the bytes gRPC received, read with `reader` (one per stream, reused) and
  // decoded without copying them first. Bytes that are no SkinResponse fail the frame.
  bool Add(const grpc::ByteBuffer& part, RawPart* reader, FrameResult* result);
  // The same for a part `reader` has parsed already (a tick's, routed by its character).
  bool Add(const RawPart& part, FrameResult* result);
  // A tick's character (tick.h): its vertex parts come with `last` false, and it is complete
  // once every instance's vertices are in; its final header comes in the tick's final part.
  void set_in_tick() { in_tick_ = true; }

 private:
  // The bytes of each vertex field; decode(field, offset, encoding, bounds, out) decodes
  // bytes of one of them (0 positions, 1 normals, 2 tangents) into `out`.
  struct FieldSizes {
    std::size_t positions = 0, normals = 0, tangents = 0;
  };
  template <typename Decode>
  bool AddPart(const v1::SkinResponse& part, FieldSizes sizes, const Decode& decode,
               FrameResult* result);
  bool Fail(const v1::SkinResponse& part, FrameResult* result, Status status);
  // The frame's one part when it went into the region: checks its ranges against the
  // mapping and points the result at them.
  bool AddRegionPart(const v1::SkinResponse& part, FrameResult* result);

  const RegionOutput* output_ = nullptr;
  bool started_ = false;
  bool failed_ = false;
  bool normals_ = false;
  bool tangents_ = false;
  bool in_tick_ = false;
  uint32_t next_instance_ = 0;
  uint32_t next_vertex_ = 0;
};

// What a frame asks of the server besides its palette.
struct SkinOptions {
  std::string backend;  // empty: the server's default
  bool want_normals = false;
  // The skinned tangents too (SkinRequest.want_tangents): needs want_normals, a mesh with
  // tangents and a backend that skins them (BackendInfo.tangents).
  bool want_tangents = false;
  SkinningMethod method = SkinningMethod::kLinear;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  // Crowd batch: palettes of this many instances back to back (1: a single instance).
  uint32_t instances = 1;
  // Same host: the server writes the answer into this region instead of sending it.
  RegionOutput output;
  // Crowds: the server sends each part as soon as its instances are skinned
  // (SkinRequest.early_parts), so compute and transport overlap.
  bool early_parts = false;
  // The frame's morph target weights, sparse (SkinRequest.morph_targets/morph_weights);
  // caller-owned, read during the call. Empty: none.
  std::span<const MorphWeight> morph_weights;
  // Crowds: each instance's own weights (SkinRequest.instance_morph_weights), one entry per
  // instance, instead of morph_weights; caller-owned, read during the call. Empty: none.
  std::span<const std::vector<MorphWeight>> instance_morph_weights;
  // Instead of a palette (which is then empty): clip layers the server samples, blends and
  // turns into the palette (SkinRequest.pose, docs/serving/animation.md). One instance.
  Pose pose;
};

// How long this client waits. Every call has a deadline; a stream (StreamFrames) has an
// idle limit instead, since it may last for hours. 0: no limit.
struct CallLimits {
  // Each unary call and each Skin frame: from the call's start to its answer.
  std::chrono::milliseconds deadline{30'000};
  // Each UploadMesh call, whole (a 1.6M-vertex mesh is ~80 MB of chunks).
  std::chrono::milliseconds upload_deadline{300'000};
  // StreamFrames: no answer for this long while frames are in flight ends the stream
  // (DEADLINE_EXCEEDED, its frames in flight reported failed) and opens the next one.
  std::chrono::milliseconds stream_idle{30'000};
};

// How the server is asked to store an upload.
struct UploadOptions {
  WeightPolicy weight_policy = WeightPolicy::kReject;
  // The rest stream as stored (MeshHeader.rest_encoding): quantized16 and quantized8-weights
  // cut the bytes a frame reads on `simd` and `simd-openmp` (docs/backends/quantized-rest.md).
  // Part of the mesh's content id: the same arrays in two encodings are two meshes.
  RestEncoding rest_encoding = RestEncoding::kFloat32;
};

class SkinClient {
 public:
  explicit SkinClient(std::shared_ptr<grpc::Channel> channel, const CallLimits& limits = {});

  grpc::Channel& channel() { return *channel_; }
  const CallLimits& limits() const { return limits_; }
  // A context for a call under `limit` (0: none).
  static void SetDeadline(grpc::ClientContext* context, std::chrono::milliseconds limit);
  v1::Skinning::Stub& stub() { return *stub_; }

  // StreamSkin and Skin with the answers as gRPC received them, to be read with RawPart
  // (which decodes the vertices without first copying them into a SkinResponse).
  using RawStream = grpc::ClientReaderWriter<v1::SkinRequest, grpc::ByteBuffer>;
  std::unique_ptr<RawStream> StreamSkinRaw(grpc::ClientContext* context);
  std::unique_ptr<grpc::ClientReader<grpc::ByteBuffer>> SkinRaw(grpc::ClientContext* context,
                                                                const v1::SkinRequest& request);

  // Uploads `arrays` unless the server already stores their content id (computed here:
  // the arrays are validated locally first, with the same errors the server would give).
  Result<v1::MeshInfo> Upload(const MeshArrays& arrays, const UploadOptions& options = {});
  // Lets this client re-upload `arrays` as `mesh_id` when a server answers NOT_FOUND,
  // without uploading now (e.g. another client of the same process uploaded it).
  void Remember(const std::string& mesh_id, std::shared_ptr<const MeshArrays> arrays,
                const UploadOptions& options = {});
  // Uploads again the mesh that had `mesh_id`, if this client uploaded it. Refused for the
  // connection's upload limit (RESOURCE_EXHAUSTED: other clients of this process are
  // re-uploading), it waits and tries again for about 1.3 s, done early once the mesh is
  // stored.
  Status Reupload(const std::string& mesh_id);
  // Uploads again what a frame's NOT_FOUND named (LostUploadOf), if this client uploaded
  // it: the mesh; a skeleton, with the clips this client uploaded for it (a server that
  // lost one lost the other: restarted, or a new replica); a clip (its skeleton first, if
  // the server lost that too). NOT_FOUND when this client never uploaded it.
  Status Reupload(const LostUpload& lost);
  Result<v1::MeshInfo> GetMesh(const std::string& mesh_id);
  Result<bool> DeleteMesh(const std::string& mesh_id);
  Result<v1::ListBackendsResponse> ListBackends();
  Result<v1::ServerStats> GetServerStats();
  // The same-host data plane, over the server's Unix socket: `region` under `name` (unique
  // among this process's regions), until UnregisterRegion (which returns once the server
  // has unmapped it) or the server's idle limit. The region is this process's: no other
  // client sees it, names it or unregisters it; ListRegions lists this process's alone.
  Result<v1::RegionInfo> RegisterRegion(const std::string& name, const SharedMemoryRegion& region);
  Status UnregisterRegion(const std::string& name);
  Result<v1::ListRegionsResponse> ListRegions();

  // One frame through Skin; on NOT_FOUND for a mesh this client uploaded, uploads it
  // again and retries once.
  Status Skin(const std::string& mesh_id, const std::string& backend,
              std::span<const float> palette, uint64_t frame, bool want_normals,
              FrameResult* result, SkinningMethod method = SkinningMethod::kLinear);
  // The same with an encoding and crowd batches. `result` is overwritten and may be reused
  // from call to call (its vectors keep their capacity); so are this client's messages.
  Status Skin(const std::string& mesh_id, std::span<const float> palette, uint64_t frame,
              const SkinOptions& options, FrameResult* result);
  // A tick (skinserve/client/tick.h) through Skin: one result per
  // character in `result`. Returns the tick's own status (a refused tick); each
  // character's own is in result->characters[i].status. A character answered NOT_FOUND
  // for a mesh this client uploaded has its mesh uploaded again and the tick is sent once
  // more.
  Status SkinTick(const Tick& tick, TickResult* result);
  // One frame of a pose instead of a palette (options.pose is set from `pose`).
  Status SkinPose(const std::string& mesh_id, const Pose& pose, uint64_t frame, SkinOptions options,
                  FrameResult* result);

  // Animation on the server (docs/serving/animation.md#uploads): a skeleton, then clips
  // built for it, each content-addressed (the same content again stores nothing new).
  Result<v1::SkeletonInfo> UploadSkeleton(const animation::Skeleton& skeleton);
  // max_error_mm: the error the server stores the clip to (UploadClipRequest.max_error_mm;
  // 0: its default, 0.01 mm); a looser bound stores fewer bytes. Re-uploads keep it.
  Result<v1::ClipInfo> UploadClip(const animation::RawClip& clip, const std::string& skeleton_id,
                                  float max_error_mm = 0);
  // Whether the server held the clip. This client no longer uploads it again.
  Result<bool> DeleteClip(const std::string& clip_id);

 private:
  Status SkinOnce(const v1::SkinRequest& request, const RegionOutput& output, RawPart* part,
                  FrameResult* result);
  Result<v1::MeshInfo> SendUpload(const MeshArrays& arrays, const UploadOptions& options);
  Status ReuploadSkeleton(const std::string& skeleton_id);
  Status ReuploadClip(const std::string& clip_id);

  std::shared_ptr<grpc::Channel> channel_;
  const CallLimits limits_;
  std::unique_ptr<v1::Skinning::Stub> stub_;
  // The two methods by name, registered with the channel as the generated stub does.
  const std::string stream_skin_name_, skin_name_;
  const grpc::internal::RpcMethod stream_skin_raw_, skin_raw_;
  std::mutex mutex_;
  struct Uploaded {
    std::shared_ptr<const MeshArrays> arrays;
    UploadOptions options;
  };
  std::map<std::string, Uploaded> uploaded_;  // by mesh id: for re-upload on NOT_FOUND
  // What UploadSkeleton and UploadClip sent, by id, likewise.
  std::map<std::string, std::shared_ptr<const animation::Skeleton>> skeletons_;
  struct UploadedClip {
    std::shared_ptr<const animation::RawClip> clip;
    std::string skeleton_id;
    float max_error_mm = 0;
  };
  std::map<std::string, UploadedClip> clips_;
  // Skin's messages, reused by whichever call holds the lock (a concurrent call uses its own).
  std::mutex skin_messages_mutex_;
  v1::SkinRequest skin_request_;
  RawPart skin_part_;
};

}  // namespace skinserve::client
