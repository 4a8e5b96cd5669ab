// UploadMesh: a header, then the arrays in chunks, put together by MeshAssembly (which
// stores the mesh only once every array is complete and valid, so a failed or truncated
// upload leaves nothing behind). Each upload is admitted by OpenUploads (the caps), its
// arrays are charged to the upload budget as they arrive, and OpenUploads' watchdog ends
// it if it makes no progress for too long, or is open too long in all.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

#include "rpc/mesh_assembly.h"
#include "rpc/open_uploads.h"
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

  // When it was admitted, and when it last made progress (MeshAssembly::progress; its
  // admission until then). Read by OpenUploads' watchdog.
  std::chrono::steady_clock::time_point admitted_at() const { return admitted_at_; }
  std::chrono::steady_clock::time_point progress_at() const {
    return std::chrono::steady_clock::time_point(
        std::chrono::steady_clock::duration(progress_at_.load()));
  }
  // While it waits for its client's next message, ends the upload with `deadline` if it
  // was admitted at `deadline_cutoff` or before, else with `idle` if it made no progress
  // since `idle_cutoff`; says which.
  UploadOverdue EndIfOverdue(std::chrono::steady_clock::time_point idle_cutoff,
                             std::chrono::steady_clock::time_point deadline_cutoff,
                             const Status& idle, const Status& deadline);
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
  const std::chrono::steady_clock::time_point admitted_at_ = std::chrono::steady_clock::now();
  std::atomic<std::chrono::steady_clock::rep> progress_at_{admitted_at_.time_since_epoch().count()};
  std::atomic<int> refs_{1};  // gRPC's (until OnDone), plus one per Hold
};

}  // namespace skinserve::server
