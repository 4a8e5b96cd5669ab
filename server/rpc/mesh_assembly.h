// MeshAssembly: an UploadMesh stream's messages put together into a mesh. The header is
// checked against the engine's limits; each chunk against the header; the mesh goes to
// the engine only once every array is complete, so a failed or truncated upload leaves
// nothing behind. Separate from the reactor so that the assembly can be tested and
// fuzzed from raw wire messages without gRPC.
//
// Memory is taken as the data arrives, never for the size a header declares: a header
// costs nothing, so a client cannot make the server hold what it has not sent. Each
// array grows with its chunks (doubling, at most to its declared size), and every growth
// is charged to the upload budget before it is allocated, old and new block together
// while the values are copied over, so the bytes all uploads hold together never exceed
// the budget, however many uploads are open or however slowly they send. The charge is
// returned once the assembly stores its mesh, is discarded or is destroyed.
#pragma once

#include <cstdint>

#include "frames/inflight_budget.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

class MeshAssembly {
 public:
  // `budget`: what the arrays are charged to; null charges nothing (fuzzing).
  explicit MeshAssembly(Engine* engine, InflightBudget* budget = nullptr)
      : engine_(engine), budget_(budget) {}
  ~MeshAssembly() { Discard(); }
  MeshAssembly(const MeshAssembly&) = delete;
  MeshAssembly& operator=(const MeshAssembly&) = delete;

  // One message of the stream; an error ends the upload (nothing is stored).
  Status Accept(const v1::UploadMeshRequest& message);
  // The client finished sending: checks every array is complete, then stores the mesh.
  // The arrays are freed (and their charge returned) either way.
  Result<MeshInfo> Store();
  // Frees whatever was received and returns its charge to the budget.
  void Discard();

  // Bytes the arrays hold now, as charged to the budget.
  uint64_t charged_bytes() const { return charged_bytes_; }
  // Grows exactly when a message makes progress: the header accepted (one), or bytes of
  // an array accepted (their number). An empty chunk adds nothing, nor does a message that
  // fails: the upload's idle limit counts time without progress (OpenUploads).
  uint64_t progress() const { return progress_; }

 private:
  Status AcceptHeader(const v1::MeshHeader& header);
  Status AcceptChunk(const v1::MeshChunk& chunk);
  template <typename T>
  Status Append(std::vector<T>& array, const char* name, const v1::MeshChunk& chunk);
  // Makes room in `array` (MeshArray `array_number`) for `values` values in all, charging
  // the growth to the budget first.
  template <typename T>
  Status Reserve(std::vector<T>& array, int array_number, uint64_t values);

  Engine* engine_;
  InflightBudget* budget_;
  bool have_header_ = false;
  bool normalize_weights_ = false;
  RestEncoding rest_encoding_ = RestEncoding::kFloat32;
  MeshArrays arrays_;
  static constexpr int kArrays = 10;  // MeshArray numbers, 0 unused
  uint64_t declared_[kArrays] = {};   // values the header implies, by MeshArray number
  uint64_t charged_[kArrays] = {};    // bytes charged for each array's block, by MeshArray number
  uint64_t charged_bytes_ = 0;
  uint64_t progress_ = 0;  // never reset: only its growth means anything
};

}  // namespace skinserve::server
