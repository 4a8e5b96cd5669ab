// UploadMesh: a header, then the arrays in chunks, put together by MeshAssembly (which
// stores the mesh only once every array is complete and valid, so a failed or truncated
// upload leaves nothing behind). Each upload is admitted by OpenUploads (the caps), its
// arrays are charged to the upload budget as they arrive, and OpenUploads' watchdog ends
// it if its client sends nothing for too long.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

#include "mesh_assembly.h"
#include "open_uploads.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class MeshUploadReactor final : public grpc::ServerReadReactor<v1::UploadMeshRequest> {
 public:
  MeshUploadReactor(Engine* engine,  // null: warming up
                    OpenUploads* uploads, const std::string& peer, v1::MeshInfo* response);
  void OnReadDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

  // Since when the upload has waited for its client's next message; time_point::max()
  // while it is busy with one (or has ended). Read by OpenUploads' watchdog.
  std::chrono::steady_clock::time_point waiting_since() const {
    return std::chrono::steady_clock::time_point(
        std::chrono::steady_clock::duration(waiting_since_.load()));
  }
  // Ends the upload with `status` if it has waited since `cutoff` or before; true if so.
  bool EndIfWaitingSince(std::chrono::steady_clock::time_point cutoff, const Status& status);
  // Keeps the reactor alive across a call from outside gRPC (OpenUploads' watchdog).
  void Hold() { refs_.fetch_add(1); }
  void Release() { Unref(); }

 private:
  Status Store();
  void ReadLocked();
  void FinishLocked(const grpc::Status& status);
  void Unref();

  OpenUploads* uploads_;
  bool registered_ = false;  // admitted by uploads_: removed at Finish
  MeshAssembly assembly_;    // touched only by the reactions, one at a time
  v1::MeshInfo* response_;
  v1::UploadMeshRequest message_;

  std::mutex mutex_;
  bool reading_ = false;
  bool finished_ = false;
  std::atomic<std::chrono::steady_clock::rep> waiting_since_{
      std::chrono::steady_clock::time_point::max().time_since_epoch().count()};
  std::atomic<int> refs_{1};  // gRPC's (until OnDone), plus one per Hold
};

}  // namespace skinserve::server
