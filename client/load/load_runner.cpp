#include "load_runner.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <deque>
#include <mutex>
#include <thread>

#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/core/reference.h"

namespace skinserve::load {
namespace {

using Clock = std::chrono::steady_clock;

// Accumulates answers from every stream into one RunResult.
class Recorder {
 public:
  Recorder(const RunConfig& config, const Workload& workload, Clock::time_point measure_from)
      : config_(config), workload_(workload), measure_from_(measure_from) {
    result_.backend = config.backend;
    result_.vertices = workload.vertices;
    result_.bones = workload.bones;
    result_.normals = workload.normals;
  }

  // One answered (or failed) frame; `late` only means something in open loop.
  void Record(const client::FrameResult& frame, double latency_ms, bool late) {
    const Clock::time_point now = Clock::now();
    bool mismatch = false, checked = false;
    if (frame.status.ok() && config_.check_every > 0 &&
        answered_.fetch_add(1) % config_.check_every == 0) {
      checked = true;
      if (config_.backend == "passthrough") {  // no compute: it must return the rest pose
        const auto rest = workload_.mesh->positions();
        mismatch =
            !std::equal(rest.begin(), rest.end(), frame.positions.begin(), frame.positions.end());
      } else {
        const Deviation d = CompareWithReference(
            *workload_.mesh, workload_.Palette(frame.frame), frame.positions,
            workload_.normals ? std::span<const float>(frame.normals) : std::span<const float>());
        mismatch = !d.within_tolerance();
      }
    }
    std::lock_guard lock(mutex_);
    result_.checked += checked;
    result_.mismatches += mismatch;
    if (!frame.status.ok()) {
      ++result_.errors[StatusCodeName(frame.status.code())];
      return;
    }
    if (now < measure_from_) return;  // warm-up
    ++result_.frames;
    result_.late += late;
    result_.latencies_ms.push_back(latency_ms);
    result_.server_queue_ms_sum += frame.timing.queued_ns() / 1e6;
    result_.server_compute_ms_sum += frame.timing.compute_ns() / 1e6;
    result_.server_encode_ms_sum += frame.timing.encode_ns() / 1e6;
    last_answer_ = std::max(last_answer_, now);
  }
  void RecordStreamError(const Status& status) {
    std::lock_guard lock(mutex_);
    ++result_.errors[StatusCodeName(status.code())];
  }
  void AddSentAndDropped(uint64_t sent, uint64_t dropped) {
    std::lock_guard lock(mutex_);
    result_.sent += sent;
    result_.dropped += dropped;
  }
  RunResult Finish(Clock::time_point stopped) {
    std::lock_guard lock(mutex_);
    const Clock::time_point end = last_answer_ > measure_from_ ? last_answer_ : stopped;
    result_.seconds = std::chrono::duration<double>(end - measure_from_).count();
    return result_;
  }

 private:
  const RunConfig& config_;
  const Workload& workload_;
  const Clock::time_point measure_from_;
  std::atomic<uint64_t> answered_{0};
  std::mutex mutex_;
  RunResult result_;
  Clock::time_point last_answer_{};
};

void ClosedLoopStream(const RunConfig& config, const Workload& workload, const std::string& mesh_id,
                      const std::atomic<bool>& stop, Recorder& recorder) {
  client::SkinClient client(client::MakeChannel(config.target));
  client.Remember(mesh_id, workload.arrays);  // re-uploads where a replica lacks the mesh
  client::StreamOptions options{.mesh_id = mesh_id,
                                .backend = config.backend,
                                .want_normals = workload.normals,
                                .frames = UINT64_MAX / 2,
                                .window = config.window,
                                .stop = &stop};
  client::StreamSummary summary;
  Status status = client::StreamFrames(
      client, options, [&](uint64_t f) { return workload.Palette(f); },
      [&](client::FrameResult& r, std::chrono::nanoseconds latency) {
        recorder.Record(r, latency.count() / 1e6, false);
      },
      &summary);
  if (!status.ok()) recorder.RecordStreamError(status);
}

// Sends frame k at start + k / rate whatever happened to earlier frames, and measures
// latency from that scheduled time, so a slow answer cannot hide the frames behind it
// (no coordinated omission). A frame whose time comes while `window` frames are still
// unanswered is dropped: not sent, and counted.
void OpenLoopStream(const RunConfig& config, const Workload& workload, const std::string& mesh_id,
                    const std::atomic<bool>& stop, Clock::time_point start, Recorder& recorder) {
  client::SkinClient client(client::MakeChannel(config.target));
  client.Remember(mesh_id, workload.arrays);
  grpc::ClientContext context;
  auto stream = client.stub().StreamSkin(&context);
  // Before the schedule starts, make sure this stream's replica holds the mesh: one frame
  // outside the schedule, re-uploading on NOT_FOUND (round_robin may place the upload on
  // another replica, hence the retries). It asks for `passthrough`, so that it never counts
  // as a frame of the backend under test on the server either.
  for (int attempt = 0; attempt < 8; ++attempt) {
    v1::SkinRequest probe;
    probe.set_mesh_id(mesh_id);
    probe.set_backend("passthrough");
    probe.set_frame(UINT64_MAX);
    probe.set_palette(client::EncodePalette(workload.Palette(0)));
    if (!stream->Write(probe)) break;
    client::FrameResult result;
    client::FrameAssembler assembler;
    v1::SkinResponse part;
    bool complete = false;
    while (!complete && stream->Read(&part)) complete = assembler.Add(part, &result);
    if (!complete || result.status.code() != StatusCode::kNotFound) break;
    if (!client.Reupload(mesh_id).ok()) break;
  }
  start = std::max(start, Clock::now());
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config.rate));
  std::mutex mutex;
  std::deque<std::pair<uint64_t, Clock::time_point>> scheduled;  // sent, unanswered
  uint64_t sent = 0, dropped = 0;

  std::thread reader([&] {
    v1::SkinResponse part;
    client::FrameResult result;
    client::FrameAssembler assembler;
    while (stream->Read(&part)) {
      if (!assembler.Add(part, &result)) continue;
      Clock::time_point due;
      {
        std::lock_guard lock(mutex);
        due = scheduled.front().second;
        scheduled.pop_front();
      }
      const auto latency = Clock::now() - due;
      recorder.Record(result, std::chrono::duration<double, std::milli>(latency).count(),
                      latency > period);
      result = client::FrameResult();
      assembler = client::FrameAssembler();
    }
  });
  for (uint64_t k = 0; !stop.load(); ++k) {
    const Clock::time_point due = start + k * period;
    std::this_thread::sleep_until(due);
    if (stop.load()) break;
    {
      std::lock_guard lock(mutex);
      if (scheduled.size() >= static_cast<std::size_t>(config.window)) {
        ++dropped;
        continue;
      }
      scheduled.push_back({k, due});
    }
    v1::SkinRequest request;
    request.set_mesh_id(mesh_id);
    request.set_backend(config.backend);
    request.set_frame(k);
    request.set_palette(client::EncodePalette(workload.Palette(k)));
    request.set_want_normals(workload.normals);
    ++sent;
    if (!stream->Write(request)) break;
  }
  stream->WritesDone();
  reader.join();
  Status status = client::FromGrpc(stream->Finish());
  {
    std::lock_guard lock(mutex);
    // Sent but never answered: failed, not lost.
    for (std::size_t i = 0; i < scheduled.size(); ++i) {
      recorder.RecordStreamError(status.ok() ? Internal("unanswered") : status);
    }
  }
  if (!status.ok() && scheduled.empty()) recorder.RecordStreamError(status);
  recorder.AddSentAndDropped(sent, dropped);
}

}  // namespace

RunResult RunLoad(const RunConfig& config, const Workload& workload, const std::string& mesh_id,
                  const Progress& progress) {
  const Clock::time_point start = Clock::now();
  const auto warmup = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.warmup_seconds));
  const auto total = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.warmup_seconds + config.duration_seconds));
  Recorder recorder(config, workload, start + warmup);
  std::atomic<bool> stop{false};
  std::vector<std::thread> streams;
  for (int s = 0; s < config.streams; ++s) {
    streams.emplace_back([&] {
      if (config.rate > 0) {
        OpenLoopStream(config, workload, mesh_id, stop, start, recorder);
      } else {
        ClosedLoopStream(config, workload, mesh_id, stop, recorder);
      }
    });
  }
  while (Clock::now() < start + total) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (progress)
      progress(std::min(1.0, (Clock::now() - start) / std::chrono::duration<double>(total)));
  }
  stop.store(true);
  const Clock::time_point stopped = Clock::now();
  for (auto& stream : streams) stream.join();
  return recorder.Finish(stopped);
}

}  // namespace skinserve::load
