// A tick's characters in a few kernel launches instead of one frame each
// (kernels/tick_skinning.cl): OpenClCopyBackend::SkinFrames hands over the frames that can
// (Takes), and they run on its lane as
//  - every palette in one write (copied one after another into the lane's pinned tick
//    palettes);
//  - every launch's rows of character table in one write;
//  - one launch per group of characters that share a chunk of the mesh arena, an influence
//    count, outputs (positions; normals; normals and tangents), the local-palette choice
//    and a target: a device memory (GPU regions: written in place at each frame's offsets)
//    or host memory (into the lane's tick outputs, read back in pieces of at most
//    kPieceBytes, each copied out of pinned memory while the later pieces still run).
// A character costs the host its palette's copy, a row of the table and (host
// output) its copy out; the device a share of a launch. On the H200 the frames each cost
// a palette write, a kernel launch and a copy (three enqueues, ~50 us of a stream's tick
// a character: docs/results/2026-11-29-gpu-encodings-ticks-h200).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <tuple>
#include <vector>

#include "backends/opencl/opencl_backend_base.h"
#include "backends/opencl/opencl_device_memory.h"
#include "backends/opencl/opencl_runtime.h"

namespace skinserve {

// Frames of this process handed to tick launches: for tests, which check that a tick's
// frames took them.
uint64_t TickLaunchFrames();

class OpenClTickLaunches {
 public:
  // Launches on `lane`. Must outlive the caller's wait for the lane (its DeviceOutputBatch's
  // Finish): the table's host copy is read by a write that may still be pending.
  OpenClTickLaunches(OpenClRuntime& runtime, OpenClLane& lane) : runtime_(runtime), lane_(lane) {}
  OpenClTickLaunches(const OpenClTickLaunches&) = delete;
  OpenClTickLaunches& operator=(const OpenClTickLaunches&) = delete;

  // Whether `frame` of `mesh` (its palette in the kernels' layout, its outputs checked
  // against the mesh) runs in a launch: linear blending of a float32 mesh in the arena, no
  // active morph target, unprofiled queues (a frame reports its own device time), and
  // float32 output into host memory, or into OpenCL device memory with every array inside
  // it at an offset that is a multiple of 4 bytes. Frames that cannot (or whose device
  // output does not fit, which the per-frame path refuses) take the per-frame path.
  static bool Takes(const OpenClRuntime& runtime, const OpenClPreparedMesh& mesh,
                    const SkinFrame& frame);
  // Frame `index` of the batch (statuses[index] in Run), which Takes.
  void Add(std::size_t index, const OpenClPreparedMesh& mesh, const SkinFrame& frame);
  bool empty() const { return characters_.empty(); }

  // Enqueues every launch; waits for the host frames and copies them out. Device memories are held
  // through `device_out`: device frames are done once the caller finishes it. Sets statuses[index]
  // of every frame added: an error of a launch's enqueue or wait fails that launch's frames (and,
  // after a failed wait, the later host pieces).
  void Run(DeviceOutputBatch& device_out, std::span<Status> statuses);
  // After the caller finished `device_out` with `finished`: the device frames fail with
  // it unless it is Ok.
  void FinishDevice(const Status& finished, std::span<Status> statuses) const;

  // Host outputs a launch reads back at most (it splits a group into pieces).
  static constexpr std::size_t kPieceBytes = std::size_t{8} << 20;
  // Host outputs of one round: its pieces enqueued, then drained, then the next round.
  static constexpr std::size_t kRoundBytes = std::size_t{64} << 20;

 private:
  struct Character {
    std::size_t index;
    const OpenClPreparedMesh* mesh;
    const SkinFrame* frame;
    int outputs;                 // 0 positions, 1 with normals, 2 with normals and tangents
    std::size_t palette_offset;  // bytes into the tick palettes (a multiple of 64)
  };
  // A launch: its characters are order_[args.first_row, End) (the table's rows alike).
  struct Launch {
    TickLaunch args;
    std::size_t host_offset = 0, host_bytes = 0;  // host launches: outputs in tick_outputs
  };
  static std::size_t End(const Launch& launch);
  // chunk, influences, outputs, local palette, target memory (null: host).
  using GroupKey = std::tuple<cl_mem, uint32_t, int, bool, cl_mem>;

  static std::size_t HostBytes(const Character& c);
  // The table's row of `c` (device outputs at its frame's offsets, host outputs at
  // `host_offset` bytes into the lane's tick outputs).
  void AppendRow(const Character& c, std::size_t host_offset);
  // The launches of each group, rows appended; host launches in pieces and rounds.
  void PlanLaunches();
  // Every palette (into pinned memory when the runtime stages, else palettes_) and the
  // table, one write each.
  Status WriteInputs(ClEvents& transfers);
  void EnqueueDeviceLaunches(DeviceOutputBatch& device_out, std::span<Status> statuses,
                             ClEvents& events);
  // A host launch's outputs read back after `kernel`: the whole piece into `pinned` at its
  // offset (staging), or each frame's arrays straight into them. *last: the last read.
  Status EnqueuePinnedRead(const Launch& launch, cl_event kernel, std::byte* pinned,
                           ClEvents& events, cl_event* last);
  Status EnqueueDirectReads(const Launch& launch, cl_event kernel, ClEvents& events,
                            cl_event* last);
  // One round of host launches [begin, end) of launches_: enqueued, read back, drained.
  void RunHostRound(std::size_t begin, std::size_t end, std::span<Status> statuses,
                    ClEvents& events, Status* failed);
  void Fail(const Launch& launch, const Status& status, std::span<Status> statuses) const;

  OpenClRuntime& runtime_;
  OpenClLane& lane_;
  std::map<GroupKey, std::vector<Character>> groups_;
  std::vector<Character> characters_;      // every frame added, in Add's order
  std::vector<Character> order_;           // the characters in launch order
  std::vector<std::size_t> host_offsets_;  // per character of order_: bytes into its round
  std::vector<uint32_t> table_;            // kTickFields per character of order_
  std::size_t palette_bytes_ = 0;          // the characters' palettes, each at its palette_offset
  std::vector<std::byte> palettes_;        // their host copy on a device sharing host memory
  std::vector<Launch> launches_;           // device launches first, then host ones in rounds
  std::vector<std::size_t> round_starts_;  // indices of launches_ starting host rounds
  std::size_t device_launches_ = 0;
  ClEvents events_;  // every command's, released after the caller's wait
};

}  // namespace skinserve
