#include "load_runner.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
#include <thread>

#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/idle_watchdog.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/tick.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::load {
namespace {

using Clock = std::chrono::steady_clock;

// A stream's shared-memory region (RunConfig::shared_memory): one slot per frame (or tick)
// in flight, each tick's slot holding its characters one after another, registered under its
// own name for the stream's life. Off: output() is disabled.
class StreamRegion {
 public:
  StreamRegion(const RunConfig& config, const Workload& workload, client::SkinClient& client)
      : client_(client) {
    if (!config.shared_memory) return;
    const uint32_t instances = std::max(config.instances, 1u);
    character_stride_ = wire::RegionFrameBytes(workload.vertices, instances, config.encoding,
                                               workload.normals, workload.tangents);
    const uint64_t stride = character_stride_ * std::max(config.characters_per_tick, 1u);
    const std::string name = client::SharedMemoryRegion::UniqueKey("load");
    auto region = client::SharedMemoryRegion::Create(
        name, stride * static_cast<uint64_t>(std::max(config.window, 1)), config.shm_dir);
    if (!region.ok()) {
      status_ = region.status();
      return;
    }
    region_ = std::move(region).value();
    if (auto registered = client.RegisterRegion(name, *region_); !registered.ok()) {
      status_ = registered.status();
      return;
    }
    output_ = {.name = name, .region = region_.get(), .offset = 0, .stride = stride};
  }
  ~StreamRegion() {
    if (output_.enabled()) (void)client_.UnregisterRegion(output_.name);  // idle-dropped anyway
  }
  const Status& status() const { return status_; }
  // stride: a frame's (or a whole tick's) bytes, the distance between slots.
  const client::RegionOutput& output() const { return output_; }
  // Ticks: one character's bytes, the distance between a tick's characters in its slot.
  uint64_t character_stride() const { return character_stride_; }

 private:
  client::SkinClient& client_;
  std::unique_ptr<client::SharedMemoryRegion> region_;
  client::RegionOutput output_;
  uint64_t character_stride_ = 0;
  Status status_;
};

// The identity pose: what `passthrough` (no compute) answers, as a palette.
std::vector<float> IdentityPalette(uint32_t joints) {
  std::vector<float> p(kFloatsPerJoint * joints, 0.0f);
  for (uint32_t j = 0; j < joints; ++j) {
    for (int r = 0; r < 3; ++r) p[kFloatsPerJoint * j + 5 * r] = 1.0f;
  }
  return p;
}

// Accumulates answers from every stream into one RunResult. Callers say whether a frame
// belongs to the measured part; errors count either way.
class Recorder {
 public:
  // `measure_from`: the start of the measured part, or Clock::time_point::max() when the
  // streams announce it (frame-count runs, StartMeasuring).
  // `meshes`: the frames' mesh, or a tick's characters' (the row describes the first).
  Recorder(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
           Clock::time_point measure_from)
      : config_(config),
        meshes_(meshes),
        workload_(*meshes.front().workload),
        identity_(IdentityPalette(workload_.joints)),
        measure_from_(measure_from) {
    const Workload& workload = workload_;
    result_.backend = config.backend;
    result_.vertices = workload.vertices;
    result_.bones = workload.bones;
    result_.normals = workload.normals;
    result_.tangents = workload.tangents;
    result_.encoding = VertexEncodingName(config.encoding);
    result_.rest_encoding = RestEncodingName(workload.rest_encoding);
    result_.instances = std::max(config.instances, 1u);
    result_.characters_per_tick = config.characters_per_tick;
    result_.data_plane = config.shared_memory ? "shm" : "grpc";
    result_.streams = config.streams;
    result_.rate = config.rate;
    if (config.rate > 0) result_.arrivals = ArrivalsName(config.arrivals);
    // Open loop knows its frame count: no reallocation while measuring.
    if (config.rate > 0) {
      result_.latencies_ms.reserve(static_cast<std::size_t>(
          config.rate * config.streams * (config.duration_seconds + config.warmup_seconds) + 1024));
    }
  }

  // Time-bounded runs: has the measured part begun (by `when`)?
  bool Measuring(Clock::time_point when = Clock::now()) {
    std::lock_guard lock(mutex_);
    return when >= measure_from_;
  }
  // Frame-count runs: the measured part begins with the first stream that starts it.
  void StartMeasuring(Clock::time_point when) {
    std::lock_guard lock(mutex_);
    measure_from_ = std::min(measure_from_, when);
  }

  // One answered (or failed) frame; `late` and `send_lag_ms` (sent minus scheduled) only
  // mean something in open loop, where the latency counts from the scheduled time.
  void Record(const client::FrameResult& frame, double latency_ms, bool late, bool measured,
              double send_lag_ms = 0) {
    const Clock::time_point now = Clock::now();
    bool mismatch = false, checked = false;
    if (frame.status.ok() && config_.check_every > 0 &&
        answered_.fetch_add(1) % config_.check_every == 0) {
      checked = true;
      mismatch = !Matches(frame, workload_);
    }
    std::lock_guard lock(mutex_);
    result_.checked += checked;
    result_.mismatches += mismatch;
    if (!frame.status.ok()) {
      ++result_.errors[StatusCodeName(frame.status.code())];
      return;
    }
    if (!measured) return;  // warm-up
    ++result_.frames;
    result_.late += late;
    result_.latencies_ms.push_back(latency_ms);
    result_.server_queue_ms_sum += frame.timing.queued_ns() / 1e6;
    result_.server_compute_ms_sum += frame.timing.compute_ns() / 1e6;
    result_.server_encode_ms_sum += frame.timing.encode_ns() / 1e6;
    const double queue = frame.timing.queued_ns() / 1e6, compute = frame.timing.compute_ns() / 1e6;
    const double encode = std::min(frame.timing.encode_ns() / 1e6, compute);
    result_.send_lag_ms_sum += send_lag_ms;
    result_.skinning_ms_sum += compute - encode;
    result_.breakdown_encode_ms_sum += encode;
    result_.transport_ms_sum += latency_ms - send_lag_ms - queue - compute;
    last_answer_ = std::max(last_answer_, now);
  }
  // One answered (or failed) tick: with check_every 1 every character of every tick is
  // checked against its own mesh's reference; with K > 1 every K-th tick checks one
  // character, the next one each time, so every character is checked over a run while a
  // check costs one character's reference on the stream's thread, not a whole tick's (64
  // references stalled a stream ~100 ms on the Xeon, which capacity counted as the
  // server's latency). Each failed character counts as an error by its code,
  // and only a tick whose characters all succeeded counts as answered. The server timing
  // columns sum the characters' (the compute the tick cost); the latency breakdown follows
  // the character that finished last on the server (queue + compute largest).
  void RecordTick(const client::TickResult& tick, double latency_ms, bool late, bool measured,
                  double send_lag_ms = 0) {
    const Clock::time_point now = Clock::now();
    uint64_t checked = 0, mismatches = 0;
    const uint64_t answer = tick.status.ok() ? answered_.fetch_add(1) : 0;
    if (tick.status.ok() && config_.check_every > 0 && answer % config_.check_every == 0) {
      const std::size_t turn = answer / config_.check_every;
      for (std::size_t c = 0; c < tick.characters.size() && c < meshes_.size(); ++c) {
        if (config_.check_every > 1 && c != turn % meshes_.size()) continue;
        if (!tick.characters[c].status.ok()) continue;
        ++checked;
        mismatches += !Matches(tick.characters[c], *meshes_[c].workload);
      }
      // A tick answering fewer characters than it carried is wrong whole.
      mismatches += tick.characters.size() != meshes_.size();
    }
    std::lock_guard lock(mutex_);
    result_.checked += checked;
    result_.mismatches += mismatches;
    if (!tick.status.ok()) {
      result_.errors[StatusCodeName(tick.status.code())] +=
          std::max<std::size_t>(tick.characters.size(), 1);
      return;
    }
    std::size_t failed = 0;
    for (const client::FrameResult& c : tick.characters) {
      if (!c.status.ok()) ++failed, ++result_.errors[StatusCodeName(c.status.code())];
    }
    if (failed > 0 || !measured) return;  // failed, or warm-up
    ++result_.frames;
    result_.late += late;
    result_.latencies_ms.push_back(latency_ms);
    const v1::ServerTiming* last = nullptr;
    for (const client::FrameResult& c : tick.characters) {
      result_.server_queue_ms_sum += c.timing.queued_ns() / 1e6;
      result_.server_compute_ms_sum += c.timing.compute_ns() / 1e6;
      result_.server_encode_ms_sum += c.timing.encode_ns() / 1e6;
      const auto end = [](const v1::ServerTiming& t) { return t.queued_ns() + t.compute_ns(); };
      if (last == nullptr || end(c.timing) > end(*last)) last = &c.timing;
    }
    const double queue = last ? last->queued_ns() / 1e6 : 0;
    const double compute = last ? last->compute_ns() / 1e6 : 0;
    const double encode = last ? std::min(last->encode_ns() / 1e6, compute) : 0;
    result_.send_lag_ms_sum += send_lag_ms;
    result_.skinning_ms_sum += compute - encode;
    result_.breakdown_encode_ms_sum += encode;
    result_.transport_ms_sum += latency_ms - send_lag_ms - queue - compute;
    last_answer_ = std::max(last_answer_, now);
  }
  // One instance of a checked frame against the float64 reference, within the bound of the
  // encoding it came in; `passthrough` (no compute) must return the rest pose. The checks
  // run on the stream's reader: all K instances of a crowd (K float64 skinnings) would
  // delay the next answers past a frame's time, so the instance checked rotates with the
  // frame number and a run covers every instance.
  // Instance k's tangents against the float64 reference: x y z within float32's rounding
  // (1e-5, times the morph deltas' magnification) plus the encoding's bound for normals, w
  // exactly the rest's. passthrough answers the rest tangents as uploaded.
  bool TangentsMatch(const client::FrameResult& frame, uint32_t k, std::span<const float> tangents,
                     const Workload& w) const {
    const Mesh& mesh = *w.mesh;
    if (tangents.size() != 4ull * mesh.vertex_count()) return false;
    const std::span<const MorphWeight> morph = w.Morph(frame.frame + k);
    std::vector<double> want;
    double magnification = 1;
    if (config_.backend == "passthrough") {
      want.assign(mesh.tangents().begin(), mesh.tangents().end());
    } else {
      const std::span<const float> palette = w.Palette(frame.frame + k);
      want =
          (w.method == SkinningMethod::kLinear ? ReferenceSkin(mesh, palette, morph)
                                               : ReferenceSkinDualQuaternion(mesh, palette, morph))
              .tangents;
      magnification = ReferenceMorphMagnitudes(mesh, morph).tangent_magnification;
    }
    if (want.size() != tangents.size()) return false;
    for (std::size_t i = 0; i < want.size(); ++i) {
      if (i % 4 == 3) {
        if (tangents[i] != want[i]) return false;
        continue;
      }
      const double bound = 1e-5 * magnification + NormalEncodingError(frame.encoding, want[i]);
      if (!(std::fabs(tangents[i] - want[i]) <= bound)) return false;  // NaN fails
    }
    return true;
  }

  bool Matches(const client::FrameResult& answer, const Workload& w) const {
    client::FrameResult decoded;
    if (answer.in_region()) {  // decoded from the region for the check only
      decoded = answer;
      if (!client::DecodeRegionFrame(&decoded).ok()) return false;
    }
    const client::FrameResult& frame = answer.in_region() ? decoded : answer;
    const uint32_t instances = std::max(config_.instances, 1u);
    if (frame.instances != instances || frame.encoding != config_.encoding) return false;
    for (uint32_t k = static_cast<uint32_t>(frame.frame % instances); k < instances;
         k += instances) {
      const std::span<const float> positions = frame.instance_positions(k);
      const std::span<const float> normals =
          w.normals ? frame.instance_normals(k) : std::span<const float>();
      if (w.normals && normals.empty()) return false;
      const std::span<const float> tangents =
          w.tangents ? frame.instance_tangents(k) : std::span<const float>();
      if (w.tangents && !TangentsMatch(frame, k, tangents, w)) return false;
      const bool passthrough = config_.backend == "passthrough";
      if (passthrough && frame.encoding == VertexEncoding::kFloat32) {
        const auto rest = w.mesh->positions();
        if (!std::equal(rest.begin(), rest.end(), positions.begin(), positions.end())) {
          return false;
        }
        continue;
      }
      const std::span<const float> palette =
          passthrough ? std::span<const float>(identity_) : w.Palette(frame.frame + k);
      if (!CompareEncodedWithReference(*w.mesh, palette, frame.encoding, frame.bounds[k], positions,
                                       normals, w.method, w.Morph(frame.frame + k))
               .within_tolerance()) {
        return false;
      }
    }
    return true;
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
  // Open loop: sends that left late, and the gaps between a stream's measured sends.
  void AddSendTiming(uint64_t late_sends, uint64_t gaps, double gap_ms_sum, double gap_ms_sq_sum) {
    std::lock_guard lock(mutex_);
    result_.late_sends += late_sends;
    result_.send_gaps += gaps;
    result_.send_gap_ms_sum += gap_ms_sum;
    result_.send_gap_ms_sq_sum += gap_ms_sq_sum;
  }
  uint64_t frames() {
    std::lock_guard lock(mutex_);
    return result_.frames;
  }
  RunResult Finish(Clock::time_point stopped) {
    std::lock_guard lock(mutex_);
    if (measure_from_ == Clock::time_point::max()) return result_;  // never measured
    const Clock::time_point end = last_answer_ > measure_from_ ? last_answer_ : stopped;
    result_.seconds = std::chrono::duration<double>(end - measure_from_).count();
    return result_;
  }

 private:
  const RunConfig& config_;
  const std::vector<UploadedMesh>& meshes_;
  const Workload& workload_;
  const std::vector<float> identity_;
  std::atomic<uint64_t> answered_{0};
  std::mutex mutex_;
  Clock::time_point measure_from_;
  RunResult result_;
  Clock::time_point last_answer_{};
};

// Keeps `window` frames in flight. Time-bounded: until `stop`, counting the answers that
// arrive after the warm-up. Frame-count: unmeasured frames until `warm`, then exactly
// `config.frames` measured ones.
void ClosedLoopStream(const RunConfig& config, const Workload& workload, const std::string& mesh_id,
                      int connection, const std::atomic<bool>& stop, const std::atomic<bool>& warm,
                      Recorder& recorder) {
  client::SkinClient client(client::MakeChannel(config.target, config.channel, connection),
                            config.limits);
  // Re-uploads where a replica lacks the mesh.
  client.Remember(mesh_id, workload.arrays, {.rest_encoding = workload.rest_encoding});
  const StreamRegion region(config, workload, client);
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  FramePalette palette(workload, config.instances);
  client::StreamOptions options{.mesh_id = mesh_id,
                                .backend = config.backend,
                                .want_normals = workload.normals,
                                .want_tangents = workload.tangents,
                                .method = workload.method,
                                .encoding = config.encoding,
                                .instances = config.instances,
                                .output = region.output(),
                                .early_parts = config.early_parts,
                                .frames = UINT64_MAX / 2,
                                .window = config.window,
                                .stop = &stop};
  // Morph weights: a single instance's straight from the workload, a crowd's per instance.
  FrameMorph morph(workload, config.instances);
  if (!workload.morph_weights.empty() && config.instances <= 1) {
    options.morph_weights = [&](uint64_t f) { return workload.Morph(f); };
  } else if (!workload.morph_weights.empty()) {
    options.instance_morph_weights = [&](uint64_t f) { return morph(f); };
  }
  const auto run = [&](bool measured_phase, uint64_t* sent) {
    const bool count_by_time = config.frames == 0;
    uint64_t measured_sent = 0;
    client::StreamSummary summary;
    Status status = client::StreamFrames(
        client, options,
        [&](uint64_t f) {
          if (measured_phase && (!count_by_time || recorder.Measuring())) ++measured_sent;
          return palette(f);
        },
        [&](client::FrameResult& r, std::chrono::nanoseconds latency) {
          const bool measured = measured_phase && (!count_by_time || recorder.Measuring());
          recorder.Record(r, latency.count() / 1e6, false, measured);
        },
        &summary);
    if (measured_phase) recorder.AddSentAndDropped(measured_sent, 0);
    if (sent != nullptr) *sent = summary.sent;
    if (!status.ok()) recorder.RecordStreamError(status);
    return status.ok();
  };
  if (config.frames == 0) {
    run(true, nullptr);
    return;
  }
  uint64_t warmup_sent = 0;
  if (config.warmup_seconds > 0) {
    options.stop = &warm;
    if (!run(false, &warmup_sent)) return;
  }
  recorder.StartMeasuring(Clock::now());
  options.stop = nullptr;
  options.first_frame = warmup_sent;
  options.frames = config.frames;
  run(true, nullptr);
}

// ClosedLoopStream for ticks: `window` ticks in flight (StreamTicks), each of every mesh's
// character, counted as ClosedLoopStream counts frames.
void ClosedLoopTickStream(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                          int connection, const std::atomic<bool>& stop,
                          const std::atomic<bool>& warm, Recorder& recorder) {
  client::SkinClient client(client::MakeChannel(config.target, config.channel, connection),
                            config.limits);
  for (const UploadedMesh& m : meshes) {  // re-uploads where a replica lacks a mesh
    client.Remember(m.mesh_id, m.workload->arrays, {.rest_encoding = m.workload->rest_encoding});
  }
  const StreamRegion region(config, *meshes.front().workload, client);
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  TickFiller fill(meshes, {config.backend, config.encoding, config.instances}, region.output(),
                  region.character_stride());
  client::TickStreamOptions options{.ticks = UINT64_MAX / 2,
                                    .window = config.window,
                                    .region_stride = region.output().stride,
                                    .stop = &stop};
  const auto run = [&](bool measured_phase, uint64_t* sent) {
    const bool count_by_time = config.frames == 0;
    uint64_t measured_sent = 0;
    client::TickStreamSummary summary;
    Status status = client::StreamTicks(
        client, options,
        [&](uint64_t f, client::Tick* tick) {
          if (measured_phase && (!count_by_time || recorder.Measuring())) ++measured_sent;
          fill(f, tick);
        },
        [&](client::TickResult& r, std::chrono::nanoseconds latency) {
          const bool measured = measured_phase && (!count_by_time || recorder.Measuring());
          recorder.RecordTick(r, latency.count() / 1e6, false, measured);
        },
        &summary);
    if (measured_phase) recorder.AddSentAndDropped(measured_sent, 0);
    if (sent != nullptr) *sent = summary.sent;
    if (!status.ok()) recorder.RecordStreamError(status);
    return status.ok();
  };
  if (config.frames == 0) {
    run(true, nullptr);
    return;
  }
  uint64_t warmup_sent = 0;
  if (config.warmup_seconds > 0) {
    options.stop = &warm;
    if (!run(false, &warmup_sent)) return;
  }
  recorder.StartMeasuring(Clock::now());
  options.stop = nullptr;
  options.first_tick = warmup_sent;
  options.ticks = config.frames;
  run(true, nullptr);
}

// Sends frame k at its time in the stream's ArrivalSchedule (constant: start + (k + stagger) /
// rate; or Poisson) whatever happened to earlier frames, and measures
// latency from that scheduled time, so a slow answer cannot hide the frames behind it
// (no coordinated omission). A frame whose time comes while `window` frames are still
// unanswered is dropped: not sent, and counted; so is a frame whose time had passed by more
// than a mean period before the stream could send at all (its call waited for a place on the
// connection, say). Whether a frame is measured depends on its
// scheduled time (time-bounded runs) or its number (frame-count runs: warm-up * rate
// frames first, then `config.frames` measured ones, then the stream ends).
// Ticks (config.characters_per_tick): each scheduled frame is a tick of every mesh's
// character, its slot of the region holding them all.
void OpenLoopStream(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                    int stream_index, int connection, const std::atomic<bool>& stop,
                    Clock::time_point start, Clock::time_point end, Recorder& recorder) {
  const Workload& workload = *meshes.front().workload;
  const std::string& mesh_id = meshes.front().mesh_id;
  const bool ticks = config.characters_per_tick > 0;
  client::SkinClient client(client::MakeChannel(config.target, config.channel, connection),
                            config.limits);
  for (const UploadedMesh& m : meshes) {
    client.Remember(m.mesh_id, m.workload->arrays, {.rest_encoding = m.workload->rest_encoding});
  }
  const StreamRegion region(config, workload, client);
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  const client::RegionOutput& output = region.output();
  grpc::ClientContext context;
  auto stream = client.StreamSkinRaw(&context);
  client::IdleWatchdog watchdog(&context, config.limits.stream_idle);
  // Before the schedule starts, make sure this stream's replica holds the mesh: one frame
  // outside the schedule, re-uploading on NOT_FOUND (round_robin may place the upload on
  // another replica, hence the retries). It asks for `passthrough`, so that it never counts
  // as a frame of the backend under test on the server either. Ticks: each mesh's.
  for (std::size_t m = 0, attempt = 0; m < meshes.size() && attempt < 8; ++attempt) {
    v1::SkinRequest probe;
    probe.set_mesh_id(meshes[m].mesh_id);
    probe.set_backend("passthrough");
    probe.set_frame(UINT64_MAX);
    // one instance, float32
    probe.set_palette(wire::EncodeFloats(meshes[m].workload->Palette(0)));
    if (!stream->Write(probe)) break;
    client::FrameResult result;
    client::FrameAssembler assembler;
    wire::RawPart part;
    grpc::ByteBuffer bytes;
    bool complete = false;
    watchdog.Awaiting(true);
    while (!complete && stream->Read(&bytes)) complete = assembler.Add(bytes, &part, &result);
    watchdog.Awaiting(false);
    if (!complete) break;
    if (result.status.code() != StatusCode::kNotFound) {
      ++m, attempt = 0;
    } else if (!client.Reupload(meshes[m].mesh_id).ok()) {
      break;
    }
  }
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / config.rate));
  const uint64_t warmup_frames =
      config.frames > 0 ? static_cast<uint64_t>(std::ceil(config.warmup_seconds * config.rate)) : 0;
  const uint64_t last_frame = config.frames > 0 ? warmup_frames + config.frames : UINT64_MAX;
  ArrivalSchedule schedule(config.arrivals, config.rate, stream_index, config.streams,
                           config.arrivals_seed);
  uint64_t k = 0;
  Clock::time_point due;
  // Frame k's time; frame-count runs start measuring at the first measured frame's.
  const auto schedule_next = [&] {
    due = start + std::chrono::duration_cast<Clock::duration>(
                      std::chrono::duration<double>(schedule.Next()));
    if (config.frames > 0 && k == warmup_frames) recorder.StartMeasuring(due);
  };
  const auto measured = [&] {
    return config.frames > 0 ? k >= warmup_frames : recorder.Measuring(due);
  };
  // The schedule began at `start` for every stream alike: frames whose time passed while
  // this one opened were not delivered.
  const Clock::time_point ready = Clock::now();
  uint64_t sent = 0, dropped = 0;  // measured frames only
  for (schedule_next(); k < last_frame && due + period < ready && due < end; schedule_next()) {
    dropped += measured();
    ++k;
  }
  struct Scheduled {
    Clock::time_point due, sent;
    bool measured;
  };
  std::mutex mutex;
  // Sent, unanswered, oldest first: a ring of `window` slots (never more are in flight).
  std::vector<Scheduled> ring(static_cast<std::size_t>(std::max(config.window, 1)));
  std::size_t ring_head = 0, in_flight = 0;
  // Ticks: the tick sent in each slot, which its answer's assembler reads.
  std::vector<client::Tick> tick_slots(ticks ? ring.size() : 0);

  std::thread reader([&] {
    // One part reader and one result for the whole run (their buffers are reused).
    wire::RawPart part;
    grpc::ByteBuffer bytes;
    client::FrameResult result;
    client::FrameAssembler assembler(&output);
    client::TickResult tick_result;
    std::optional<client::TickAssembler> tick_assembler;
    while (stream->Read(&bytes)) {
      watchdog.Answered();
      if (ticks && !tick_assembler) {  // the oldest tick in flight: answers come in order
        std::lock_guard lock(mutex);
        tick_assembler.emplace(tick_slots[ring_head], &tick_result);
      }
      if (ticks ? !tick_assembler->Add(bytes, &part) : !assembler.Add(bytes, &part, &result)) {
        continue;
      }
      const Clock::time_point answered = Clock::now();
      Scheduled frame;
      {
        std::lock_guard lock(mutex);
        frame = ring[ring_head];
      }
      const auto latency = answered - frame.due;
      const double latency_ms = std::chrono::duration<double, std::milli>(latency).count();
      const double lag_ms =
          std::chrono::duration<double, std::milli>(frame.sent - frame.due).count();
      if (ticks) {
        recorder.RecordTick(tick_result, latency_ms, latency > period, frame.measured, lag_ms);
      } else {
        recorder.Record(result, latency_ms, latency > period, frame.measured, lag_ms);
      }
      {  // only now may the frame's slot (and its range of a region) take the next frame
        std::lock_guard lock(mutex);
        ring_head = (ring_head + 1) % ring.size();
        --in_flight;
        watchdog.Awaiting(in_flight > 0);
      }
      assembler = client::FrameAssembler(&output);
      tick_assembler.reset();
    }
  });
  FramePalette palette(workload, config.instances);
  FrameMorph morph(workload, config.instances);
  TickFiller fill(meshes, {config.backend, config.encoding, config.instances}, output,
                  region.character_stride());
  v1::SkinRequest request;  // reused: only the frame number and the palette change
  if (!ticks) request.set_mesh_id(mesh_id);
  if (!ticks) {
    request.set_backend(config.backend);
    request.set_want_normals(workload.normals);
    request.set_want_tangents(workload.tangents);
    request.set_encoding(static_cast<v1::Encoding>(config.encoding));
    request.set_instances(config.instances);
    request.set_pack_instances(true);  // FrameAssembler takes packed parts
    request.set_method(wire::ToWire(workload.method));
    if (output.enabled()) request.mutable_output()->set_region(output.name);
    request.set_early_parts(config.early_parts);
  }
  uint64_t late_sends = 0, gaps = 0;
  double gap_ms_sum = 0, gap_ms_sq_sum = 0;
  Clock::time_point previous_send{};  // of the last measured frame sent, if it was the last
  for (; k < last_frame && due < end && !stop.load(); ++k, schedule_next()) {
    std::this_thread::sleep_until(due);
    if (stop.load()) break;
    const bool counted = measured();
    const Clock::time_point sent_at = Clock::now();
    std::size_t slot = 0;
    {
      std::lock_guard lock(mutex);
      if (in_flight >= ring.size()) {
        dropped += counted;
        previous_send = {};
        continue;
      }
      slot = (ring_head + in_flight++) % ring.size();
      ring[slot] = {due, sent_at, counted};
      watchdog.Awaiting(true);
      // Frames in flight take the ring's slots in turn: each its own range of the region.
      if (output.enabled()) request.mutable_output()->set_offset(slot * output.stride);
    }
    request.set_frame(k);
    if (ticks) {  // the slot is this tick's until its answer: the reader reads it then
      client::Tick& tick = tick_slots[slot];
      tick.Clear();
      tick.set_frame(k);
      fill(k, &tick);
      tick.ToWire(&request, slot * output.stride);
    } else {
      wire::EncodeFloats(palette(k), request.mutable_palette());
      if (!workload.morph_weights.empty() && config.instances <= 1) {
        wire::MorphWeightsToWire(workload.Morph(k), &request);
      } else if (!workload.morph_weights.empty()) {
        wire::InstanceMorphWeightsToWire(morph(k), &request);
      }
    }
    if (counted) {
      ++sent;
      late_sends += sent_at - due > std::chrono::duration<double, std::milli>(kLateSendMs);
      if (previous_send != Clock::time_point{}) {
        const double gap =
            std::chrono::duration<double, std::milli>(sent_at - previous_send).count();
        ++gaps;
        gap_ms_sum += gap;
        gap_ms_sq_sum += gap * gap;
      }
    }
    previous_send = counted ? sent_at : Clock::time_point{};
    if (!stream->Write(request)) break;
  }
  recorder.AddSendTiming(late_sends, gaps, gap_ms_sum, gap_ms_sq_sum);
  stream->WritesDone();
  reader.join();
  Status status = wire::FromGrpc(stream->Finish());
  if (watchdog.fired()) {
    status = DeadlineExceeded(
        fmt::format("no answer for {:.1f} s with frames in flight (--stream-idle-seconds)",
                    watchdog.limit().count() / 1000.0));
  }
  {
    std::lock_guard lock(mutex);
    // Sent but never answered: failed, not lost.
    for (std::size_t i = 0; i < in_flight; ++i) {
      recorder.RecordStreamError(status.ok() ? Internal("unanswered") : status);
    }
  }
  if (!status.ok() && in_flight == 0) recorder.RecordStreamError(status);
  recorder.AddSentAndDropped(sent, dropped);
}

}  // namespace

RunResult RunLoad(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                  const Progress& progress, const MeasuredPartHooks& hooks) {
  bool begun = false;
  const auto begin = [&] {
    if (!begun && hooks.begin) hooks.begin();
    begun = true;
  };
  // No warm-up: the measured part starts with the streams, so `begin` goes first.
  if (config.warmup_seconds <= 0) begin();
  const Clock::time_point start = Clock::now();
  const auto warmup = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.warmup_seconds));
  const auto total = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config.warmup_seconds + config.duration_seconds));
  const bool by_frames = config.frames > 0;
  Recorder recorder(config, meshes, by_frames ? Clock::time_point::max() : start + warmup);
  std::atomic<bool> stop{false}, warm{false};
  std::atomic<int> running{config.streams};
  std::vector<std::thread> streams;
  for (int s = 0; s < config.streams; ++s) {
    const int connection = s / std::max(config.streams_per_connection, 1);
    streams.emplace_back([&, s, connection] {
      if (config.rate > 0) {
        OpenLoopStream(config, meshes, s, connection, stop, start,
                       by_frames ? Clock::time_point::max() : start + total, recorder);
      } else if (config.characters_per_tick > 0) {
        ClosedLoopTickStream(config, meshes, connection, stop, warm, recorder);
      } else {
        ClosedLoopStream(config, *meshes.front().workload, meshes.front().mesh_id, connection, stop,
                         warm, recorder);
      }
      --running;
    });
  }
  const auto report = [&](double fraction) {
    if (progress) progress(std::clamp(fraction, 0.0, 1.0));
  };
  // Ticks of 100 ms for the progress bar, one falling on the end of the warm-up; `begin`
  // there (before closed-loop streams are let into their measured phase).
  const auto tick = [&] {
    Clock::time_point next = Clock::now() + std::chrono::milliseconds(100);
    if (!begun) next = std::min(next, start + warmup);
    std::this_thread::sleep_until(next);
    if (!begun && Clock::now() >= start + warmup) begin();
  };
  if (by_frames) {
    const double wanted = static_cast<double>(config.frames) * config.streams;
    while (running.load() > 0) {
      tick();
      if (begun) warm.store(true);
      report(recorder.frames() / wanted);
    }
  } else {
    while (Clock::now() < start + total) {
      tick();
      report((Clock::now() - start) / std::chrono::duration<double>(total));
    }
  }
  report(1.0);
  stop.store(true);
  const Clock::time_point stopped = Clock::now();
  for (auto& stream : streams) stream.join();
  begin();  // streams that ended within the warm-up: an empty measured part
  if (hooks.end) hooks.end();
  return recorder.Finish(stopped);
}

}  // namespace skinserve::load
