// FrameJob: one frame on its way through the server, reused frame after frame by its
// stream so that the steady state allocates nothing. It owns the palette the engine reads,
// the buffers the engine skins into and the response parts the answer is encoded into
// (each at most 1 MiB of vertex data, so no message needs more than gRPC's default
// 4 MiB); all grow to the largest frame seen and are charged to the in-flight budget
// until the job is destroyed (its stream ends). Each instance of a crowd is encoded on the
// compute thread that skinned it, right after it (OnInstanceSkinned).
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "inflight_budget.h"
#include "metrics_frames.h"
#include "skinserve/core/engine.h"
#include "skinserve/core/vertex_encoding.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

inline constexpr std::size_t kMaxPartPayloadBytes = 1 << 20;

class FrameJob final : public SkinJob {
 public:
  // Told on a compute thread once the frame's answer is ready (or failed).
  class Listener {
   public:
    virtual void OnFrameDone(FrameJob* job) = 0;

   protected:
    ~Listener() = default;
  };

  FrameJob(Listener* listener, InflightBudget* budget) : listener_(listener), budget_(budget) {}
  ~FrameJob() override;

  // Prepares `request` for the engine: checks what the server must know before sizing
  // buffers (mesh, encoding, batch limits, budget), decodes the palette and sizes the
  // outputs. Then Engine::Submit(this). Non-OK: the frame failed before the engine.
  Status Prepare(const v1::SkinRequest& request, const Engine& engine,
                 const std::string& default_backend);
  // The frame failed before the engine: it is answered with `status`.
  void Fail(Status status);

  bool done() const { return done_; }  // under the listener's lock
  void set_done() { done_ = true; }
  const Status& status() const { return result_; }
  uint64_t frame() const { return frame_; }
  // The next response part; nullptr once every part was handed out. `*last` tells
  // whether it is the frame's final part.
  const v1::SkinResponse* NextPart(bool* last);

 private:
  // Encodes instance `instance` into its parts, on the thread that skinned it.
  Status OnInstanceSkinned(uint32_t instance) override;
  void OnSkinned(Status status, const FrameTiming& timing) override;
  // Instance i's parts, after ComputeBounds for snorm16 (all but a part skinned in place).
  Status EncodeInstance(uint32_t i);
  // What is left once every instance is encoded: the in-place part's fields, `last`, the
  // timings.
  void FinishParts();
  void SetErrorPart();

  Listener* const listener_;
  InflightBudget* const budget_;
  uint64_t charged_ = 0;  // bytes of this job's buffers charged to the budget

  MeshInfo mesh_;
  uint64_t frame_ = 0;
  uint32_t instances_ = 1;
  bool want_normals_ = false;
  VertexEncoding encoding_ = VertexEncoding::kFloat32;
  std::vector<float> palette_;
  std::vector<float> positions_;  // sized to the largest frame; spans cover the current
  std::vector<float> normals_;
  std::vector<v1::SkinResponse> parts_;
  // A float32 frame of one instance in one part is skinned straight into that part's
  // bytes: no copy besides gRPC's serialisation.
  bool in_place_ = false;
  std::size_t part_count_ = 0;
  uint32_t vertices_per_part_ = 1;  // at most 1 MiB of encoded vertex data per part
  std::size_t parts_per_instance_ = 1;
  std::atomic<int64_t> encode_ns_{0};  // summed over instances (they may run in parallel)
  std::size_t next_part_ = 0;
  Status result_;
  FrameTiming timing_;
  bool done_ = false;
  FrameRecord record_;  // for the metrics
};

}  // namespace skinserve::server
