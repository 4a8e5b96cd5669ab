// MeshAssembly: an UploadMesh stream's messages put together into a mesh. The header is
// checked against the engine's limits before anything is allocated; each chunk against
// the header; the mesh goes to the engine only once every array is complete, so a failed
// or truncated upload leaves nothing behind. Separate from the reactor so that the
// assembly can be tested and fuzzed from raw wire messages without gRPC.
#pragma once

#include <cstdint>

#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

class MeshAssembly {
 public:
  explicit MeshAssembly(Engine* engine) : engine_(engine) {}

  // One message of the stream; an error ends the upload (nothing is stored).
  Status Accept(const v1::UploadMeshRequest& message);
  // The client finished sending: checks every array is complete, then stores the mesh.
  Result<MeshInfo> Store();

 private:
  Status AcceptHeader(const v1::MeshHeader& header);
  Status AcceptChunk(const v1::MeshChunk& chunk);

  Engine* engine_;
  bool have_header_ = false;
  bool normalize_weights_ = false;
  MeshArrays arrays_;
  uint64_t received_[5] = {};  // values received so far, by MeshArray number
};

}  // namespace skinserve::server
