// UploadMesh: a header, then the arrays in chunks. The header is checked against the
// limits before anything is allocated; each chunk against the header; the mesh is stored
// only once every array is complete and valid, so a failed or truncated upload leaves
// nothing behind.
#pragma once

#include <grpcpp/grpcpp.h>

#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class MeshUploadReactor final : public grpc::ServerReadReactor<v1::UploadMeshRequest> {
 public:
  MeshUploadReactor(Engine* engine, v1::MeshInfo* response);  // null: warming up
  void OnReadDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  Status Accept(const v1::UploadMeshRequest& message);
  Status AcceptHeader(const v1::MeshHeader& header);
  Status AcceptChunk(const v1::MeshChunk& chunk);
  Status Store();

  Engine* engine_;
  v1::MeshInfo* response_;
  v1::UploadMeshRequest message_;
  bool have_header_ = false;
  bool normalize_weights_ = false;
  MeshArrays arrays_;
  uint64_t received_[5] = {};  // values received so far, by MeshArray number
};

}  // namespace skinserve::server
