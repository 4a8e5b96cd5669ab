// SkinClient: the C++ client library of skinserve.v1.Skinning. It uploads meshes in
// chunks (skipping content the server already has), skins single frames, and remembers
// what it uploaded so that a server answering NOT_FOUND (restarted, or a new replica)
// gets the mesh again transparently.
#pragma once

#include <grpcpp/grpcpp.h>

#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "skinserve/core/mesh.h"
#include "skinserve/core/skinning_method.h"
#include "skinserve/core/status.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::client {

inline constexpr std::size_t kUploadChunkBytes = 1 << 20;

// One frame as the server returned it, reassembled from its parts.
struct FrameResult {
  uint64_t frame = 0;
  Status status;  // the frame's own error, if it failed
  std::vector<float> positions;
  std::vector<float> normals;
  v1::ServerTiming timing;
};

// Gathers a frame's parts; true once the part with `last` has arrived.
class FrameAssembler {
 public:
  // Adds `part` to `result`; an error part or a part outside the frame's range sets
  // result->status.
  bool Add(const v1::SkinResponse& part, FrameResult* result);

 private:
  uint32_t received_ = 0;
};

class SkinClient {
 public:
  explicit SkinClient(std::shared_ptr<grpc::Channel> channel);

  grpc::Channel& channel() { return *channel_; }
  v1::Skinning::Stub& stub() { return *stub_; }

  // Uploads `arrays` unless the server already stores their content id (computed here:
  // the arrays are validated locally first, with the same errors the server would give).
  Result<v1::MeshInfo> Upload(const MeshArrays& arrays,
                              WeightPolicy weight_policy = WeightPolicy::kReject);
  // Lets this client re-upload `arrays` as `mesh_id` when a server answers NOT_FOUND,
  // without uploading now (e.g. another client of the same process uploaded it).
  void Remember(const std::string& mesh_id, std::shared_ptr<const MeshArrays> arrays,
                WeightPolicy weight_policy = WeightPolicy::kReject);
  // Uploads again the mesh that had `mesh_id`, if this client uploaded it.
  Status Reupload(const std::string& mesh_id);
  Result<v1::MeshInfo> GetMesh(const std::string& mesh_id);
  Result<bool> DeleteMesh(const std::string& mesh_id);
  Result<v1::ListBackendsResponse> ListBackends();
  Result<v1::ServerStats> GetServerStats();

  // One frame through Skin; on NOT_FOUND for a mesh this client uploaded, uploads it
  // again and retries once.
  Status Skin(const std::string& mesh_id, const std::string& backend,
              std::span<const float> palette, uint64_t frame, bool want_normals,
              FrameResult* result, SkinningMethod method = SkinningMethod::kLinear);

 private:
  Status SkinOnce(const v1::SkinRequest& request, FrameResult* result);
  Result<v1::MeshInfo> SendUpload(const MeshArrays& arrays, WeightPolicy weight_policy);

  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::Skinning::Stub> stub_;
  std::mutex mutex_;
  struct Uploaded {
    std::shared_ptr<const MeshArrays> arrays;
    WeightPolicy weight_policy;
  };
  std::map<std::string, Uploaded> uploaded_;  // by mesh id: for re-upload on NOT_FOUND
};

// Encodes a palette for the wire.
std::string EncodePalette(std::span<const float> palette);
// The wire's name of a skinning method.
v1::SkinningMethod WireMethod(SkinningMethod method);

}  // namespace skinserve::client
