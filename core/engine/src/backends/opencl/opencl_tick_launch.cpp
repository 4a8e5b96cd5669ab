#include "backends/opencl/opencl_tick_launch.h"

#include <algorithm>
#include <atomic>
#include <cstring>

#include "backends/opencl/opencl_morph.h"
#include "device_output_checks.h"

namespace skinserve {
namespace {

constexpr uint64_t kWord = sizeof(uint32_t);
// The tables' offsets are 32-bit words: outputs must end below this.
constexpr uint64_t kWordAddressable = uint64_t{4} << 30 << 2;

std::atomic<uint64_t> tick_launch_frames{0};

int HostOutputs(const SkinFrame& frame) {
  return !frame.tangents.empty() ? 2 : (!frame.normals.empty() ? 1 : 0);
}

int DeviceOutputs(const DeviceOutput& d) { return d.tangents ? 2 : (d.normals ? 1 : 0); }

}  // namespace

uint64_t TickLaunchFrames() { return tick_launch_frames.load(); }

bool OpenClTickLaunches::Takes(const OpenClRuntime& runtime, const OpenClPreparedMesh& mesh,
                               const SkinFrame& frame) {
  if (!runtime.tick_launches() || mesh.arena == nullptr ||
      frame.method != SkinningMethod::kLinear || runtime.device_timing() ||
      frame.encoded.active() || MorphsOnDevice(frame, mesh.morph)) {
    return false;
  }
  const DeviceOutput& d = frame.device;
  if (!d.active()) return true;
  if (d.encoding != VertexEncoding::kFloat32 || OpenClDeviceMemoryBuffer(*d.memory) == nullptr) {
    return false;
  }
  const uint64_t v = mesh.mesh().vertex_count(), size = d.memory->byte_size();
  const auto fits = [&](uint64_t offset, uint64_t bytes) {
    return offset % kWord == 0 && RangeInside(offset, bytes, size) &&
           offset + bytes <= kWordAddressable;
  };
  return fits(d.positions_offset, 12 * v) && (!d.normals || fits(d.normals_offset, 12 * v)) &&
         (!d.tangents || fits(d.tangents_offset, 16 * v));
}

void OpenClTickLaunches::Add(std::size_t index, const OpenClPreparedMesh& mesh,
                             const SkinFrame& frame) {
  const bool device = frame.device.active();
  const Character c{index, &mesh, &frame, device ? DeviceOutputs(frame.device) : HostOutputs(frame),
                    palette_bytes_};
  palette_bytes_ += (frame.palette.size_bytes() + 63) / 64 * 64;
  characters_.push_back(c);
  tick_launch_frames.fetch_add(1, std::memory_order_relaxed);
  const GroupKey key{mesh.arena->chunk(), mesh.mesh().influences(), c.outputs,
                     runtime_.UsesLocalPalette(mesh.mesh(), SkinningMethod::kLinear),
                     device ? OpenClDeviceMemoryBuffer(*frame.device.memory) : nullptr};
  groups_[key].push_back(c);
}

std::size_t OpenClTickLaunches::HostBytes(const Character& c) {
  return c.frame->positions.size_bytes() + c.frame->normals.size_bytes() +
         c.frame->tangents.size_bytes();
}

void OpenClTickLaunches::AppendRow(const Character& c, std::size_t host_offset) {
  const OpenClPreparedMesh& m = *c.mesh;
  const SkinFrame& f = *c.frame;
  const uint64_t v = m.mesh().vertex_count();
  uint64_t out[3];  // positions, normals, tangents: bytes into the launch's output
  if (f.device.active()) {
    out[0] = f.device.positions_offset, out[1] = f.device.normals_offset,
    out[2] = f.device.tangents_offset;
  } else {
    out[0] = host_offset, out[1] = host_offset + 12 * v, out[2] = host_offset + 24 * v;
  }
  const auto word = [](uint64_t bytes) { return static_cast<uint32_t>(bytes / kWord); };
  const uint32_t row[kTickFields] = {static_cast<uint32_t>(v),
                                     word(c.palette_offset),
                                     m.joints_word,
                                     m.weights_word,
                                     m.positions_word,
                                     word(out[0]),
                                     c.outputs >= 1 ? m.normals_word : 0,
                                     c.outputs >= 1 ? word(out[1]) : 0,
                                     c.outputs == 2 ? m.tangents_word : 0,
                                     c.outputs == 2 ? word(out[2]) : 0,
                                     m.mesh().joint_count() * 12};
  table_.insert(table_.end(), std::begin(row), std::end(row));
}

void OpenClTickLaunches::PlanLaunches() {
  const auto open = [&](const GroupKey& key) {
    Launch launch{};
    launch.args.arena = std::get<0>(key);
    launch.args.influences = std::get<1>(key);
    launch.args.outputs = std::get<2>(key);
    launch.args.local = std::get<3>(key);
    launch.args.out = std::get<4>(key);
    launch.args.first_row = static_cast<uint32_t>(order_.size());
    launches_.push_back(launch);
  };
  const auto append = [&](const Character& c, std::size_t host_offset) {
    Launch& launch = launches_.back();
    launch.args.characters++;
    launch.args.most_vertices = std::max(launch.args.most_vertices, c.mesh->mesh().vertex_count());
    launch.args.staged_bytes = std::max<std::size_t>(
        launch.args.staged_bytes, c.mesh->mesh().joint_count() * 12 * sizeof(float));
    order_.push_back(c);
    host_offsets_.push_back(host_offset);
    AppendRow(c, host_offset);
  };
  for (const auto& [key, characters] : groups_) {  // device memory: one launch a group
    if (std::get<4>(key) == nullptr) continue;
    open(key);
    for (const Character& c : characters) append(c, 0);
  }
  device_launches_ = launches_.size();
  std::size_t round_bytes = kRoundBytes;           // none open yet
  for (const auto& [key, characters] : groups_) {  // host memory: pieces, in rounds
    if (std::get<4>(key) != nullptr) continue;
    bool opened = false;
    for (const Character& c : characters) {
      const std::size_t bytes = HostBytes(c);
      if (round_bytes + bytes > kRoundBytes) {
        round_starts_.push_back(launches_.size());
        round_bytes = 0;
        opened = false;
      }
      if (!opened || launches_.back().host_bytes + bytes > kPieceBytes) {
        open(key);
        launches_.back().host_offset = round_bytes;
        opened = true;
      }
      append(c, round_bytes);
      launches_.back().host_bytes += bytes;
      round_bytes += bytes;
    }
  }
}

Status OpenClTickLaunches::WriteInputs(ClEvents& transfers) {
  std::byte* palettes = nullptr;
  if (runtime_.staging()) {
    if (Status s = runtime_.GrowPinned(lane_.compute, "pinned tick palettes", palette_bytes_,
                                       &lane_.pinned_tick_palettes);
        !s.ok()) {
      return s;
    }
    palettes = static_cast<std::byte*>(lane_.pinned_tick_palettes.host);
  } else {
    palettes_.resize(palette_bytes_);
    palettes = palettes_.data();
  }
  for (const Character& c : characters_) {
    std::memcpy(palettes + c.palette_offset, c.frame->palette.data(),
                c.frame->palette.size_bytes());
  }
  const std::size_t table_bytes = table_.size() * sizeof(uint32_t);
  if (Status s = runtime_.GrowBuffer("tick palettes", CL_MEM_READ_ONLY, palette_bytes_,
                                     &lane_.tick_palettes, &lane_.tick_palettes_bytes);
      !s.ok()) {
    return s;
  }
  if (Status s = runtime_.GrowBuffer("tick tables", CL_MEM_READ_ONLY, table_bytes,
                                     &lane_.tick_tables, &lane_.tick_tables_bytes);
      !s.ok()) {
    return s;
  }
  // Non-blocking: the palettes' memory (the lane's, or palettes_) and table_ stay put until
  // the caller's wait.
  if (cl_int err = clEnqueueWriteBuffer(lane_.compute, lane_.tick_palettes.get(), CL_FALSE, 0,
                                        palette_bytes_, palettes, 0, nullptr, transfers.Next());
      err != CL_SUCCESS) {
    return ClError("clEnqueueWriteBuffer(tick palettes)", err);
  }
  if (cl_int err = clEnqueueWriteBuffer(lane_.compute, lane_.tick_tables.get(), CL_FALSE, 0,
                                        table_bytes, table_.data(), 0, nullptr, transfers.Next());
      err != CL_SUCCESS) {
    return ClError("clEnqueueWriteBuffer(tick tables)", err);
  }
  for (Launch& launch : launches_) {
    launch.args.palettes = lane_.tick_palettes.get();
    launch.args.table = lane_.tick_tables.get();
  }
  return Status::Ok();
}

std::size_t OpenClTickLaunches::End(const Launch& launch) {
  return std::size_t{launch.args.first_row} + launch.args.characters;
}

void OpenClTickLaunches::Fail(const Launch& launch, const Status& status,
                              std::span<Status> statuses) const {
  for (std::size_t k = launch.args.first_row; k < End(launch); ++k) {
    statuses[order_[k].index] = status;
  }
}

void OpenClTickLaunches::EnqueueDeviceLaunches(DeviceOutputBatch& device_out,
                                               std::span<Status> statuses, ClEvents& events) {
  for (std::size_t l = 0; l < device_launches_; ++l) {
    const Launch& launch = launches_[l];
    // The memory held (acquired) before the kernel that writes it.
    Status s = device_out.Hold(*order_[launch.args.first_row].frame, events);
    if (s.ok()) s = runtime_.EnqueueTick(lane_, launch.args, events.Next());
    Fail(launch, s, statuses);  // Ok too: the caller's Finish has the last word
  }
  clFlush(lane_.compute);
}

Status OpenClTickLaunches::EnqueuePinnedRead(const Launch& launch, cl_event kernel,
                                             std::byte* pinned, ClEvents& events, cl_event* last) {
  cl_event* event = events.Next();
  if (cl_int err = clEnqueueReadBuffer(lane_.transfer, lane_.tick_outputs.get(), CL_FALSE,
                                       launch.host_offset, launch.host_bytes,
                                       pinned + launch.host_offset, 1, &kernel, event);
      err != CL_SUCCESS) {
    return ClError("clEnqueueReadBuffer(tick outputs)", err);
  }
  *last = *event;
  return Status::Ok();
}

Status OpenClTickLaunches::EnqueueDirectReads(const Launch& launch, cl_event kernel,
                                              ClEvents& events, cl_event* last) {
  for (std::size_t k = launch.args.first_row; k < End(launch); ++k) {
    const SkinFrame& f = *order_[k].frame;
    std::size_t offset = host_offsets_[k];
    for (std::span<float> to : {f.positions, f.normals, f.tangents}) {
      if (to.empty()) continue;
      cl_event* event = events.Next();
      if (cl_int err = clEnqueueReadBuffer(lane_.transfer, lane_.tick_outputs.get(), CL_FALSE,
                                           offset, to.size_bytes(), to.data(), 1, &kernel, event);
          err != CL_SUCCESS) {
        return ClError("clEnqueueReadBuffer(tick outputs)", err);
      }
      *last = *event;
      offset += to.size_bytes();
    }
  }
  return Status::Ok();
}

void OpenClTickLaunches::RunHostRound(std::size_t begin, std::size_t end,
                                      std::span<Status> statuses, ClEvents& events,
                                      Status* failed) {
  std::size_t round_bytes = 0;
  for (std::size_t l = begin; l < end; ++l) {
    round_bytes = std::max(round_bytes, launches_[l].host_offset + launches_[l].host_bytes);
  }
  Status grown = runtime_.GrowBuffer("tick outputs", CL_MEM_READ_WRITE, round_bytes,
                                     &lane_.tick_outputs, &lane_.tick_outputs_bytes);
  const bool staging = runtime_.staging();
  if (grown.ok() && staging) {
    grown = runtime_.GrowPinned(lane_.compute, "pinned batch outputs", round_bytes,
                                &lane_.pinned_batch_outputs);
  }
  auto* pinned = static_cast<std::byte*>(lane_.pinned_batch_outputs.host);
  std::vector<cl_event> last(end - begin, nullptr);  // each launch's last read (owned by events)
  for (std::size_t l = begin; l < end && grown.ok(); ++l) {
    Launch& launch = launches_[l];
    launch.args.out = lane_.tick_outputs.get();
    cl_event* kernel = events.Next();
    Status s = runtime_.EnqueueTick(lane_, launch.args, kernel);
    // The reads on the transfer queue after the kernel: they overlap the next launch.
    if (s.ok()) {
      s = staging ? EnqueuePinnedRead(launch, *kernel, pinned, events, &last[l - begin])
                  : EnqueueDirectReads(launch, *kernel, events, &last[l - begin]);
    }
    if (!s.ok()) {
      Fail(launch, s, statuses);
      last[l - begin] = nullptr;
    }
    clFlush(lane_.compute);
    clFlush(lane_.transfer);
  }
  for (std::size_t l = begin; l < end; ++l) {
    const Launch& launch = launches_[l];
    if (!grown.ok()) {
      Fail(launch, grown, statuses);
      continue;
    }
    if (last[l - begin] == nullptr) continue;  // failed at its enqueue
    if (failed->ok()) {
      if (cl_int err = clWaitForEvents(1, &last[l - begin]); err != CL_SUCCESS) {
        *failed = ClError("clWaitForEvents(tick read-back)", err);
        clFinish(lane_.compute);  // nothing of the round still runs into its memory
        clFinish(lane_.transfer);
      }
    }
    if (!failed->ok()) {
      Fail(launch, *failed, statuses);
      continue;
    }
    for (std::size_t k = launch.args.first_row; k < End(launch); ++k) {
      const SkinFrame& f = *order_[k].frame;
      if (staging) {
        std::size_t offset = host_offsets_[k];
        for (std::span<float> to : {f.positions, f.normals, f.tangents}) {
          if (to.empty()) continue;  // (memcpy takes no null pointer, even for 0 bytes)
          std::memcpy(to.data(), pinned + offset, to.size_bytes());
          offset += to.size_bytes();
        }
      }
      statuses[order_[k].index] = Status::Ok();
    }
  }
}

void OpenClTickLaunches::Run(DeviceOutputBatch& device_out, std::span<Status> statuses) {
  if (characters_.empty()) return;
  PlanLaunches();
  ClEvents& events = events_;  // released with this object, after the caller's wait
  if (Status s = WriteInputs(events); !s.ok()) {
    for (const Character& c : characters_) statuses[c.index] = s;
    launches_.clear();
    return;
  }
  EnqueueDeviceLaunches(device_out, statuses, events);
  Status failed;
  round_starts_.push_back(launches_.size());
  for (std::size_t r = 0; r + 1 < round_starts_.size(); ++r) {
    RunHostRound(round_starts_[r], round_starts_[r + 1], statuses, events, &failed);
  }
}

void OpenClTickLaunches::FinishDevice(const Status& finished, std::span<Status> statuses) const {
  if (finished.ok()) return;
  for (std::size_t l = 0; l < device_launches_ && l < launches_.size(); ++l) {
    Fail(launches_[l], finished, statuses);
  }
}

}  // namespace skinserve
