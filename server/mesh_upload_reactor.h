// UploadMesh: a header, then the arrays in chunks, put together by MeshAssembly (which
// stores the mesh only once every array is complete and valid, so a failed or truncated
// upload leaves nothing behind).
#pragma once

#include <grpcpp/grpcpp.h>

#include "mesh_assembly.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class MeshUploadReactor final : public grpc::ServerReadReactor<v1::UploadMeshRequest> {
 public:
  MeshUploadReactor(Engine* engine, v1::MeshInfo* response);  // null: warming up
  void OnReadDone(bool ok) override;
  void OnDone() override { delete this; }

 private:
  Status Store();

  MeshAssembly assembly_;
  v1::MeshInfo* response_;
  v1::UploadMeshRequest message_;
};

}  // namespace skinserve::server
