#include "load_runner.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "pose_check.h"
#include "pose_workload.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/idle_watchdog.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/tick.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/wire/region_layout.h"
#include "unit_stream.h"

namespace skinserve::load {
namespace {

// Re-uploads of lost meshes an open-loop stream tries in a row before it gives up (as
// client::StreamOptions::max_reuploads).
constexpr int kMaxReuploadsInARow = 8;

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
    result_.data_plane = !config.frame_socket.empty() ? "socket"
                         : config.shared_memory       ? "shm"
                                                      : "grpc";
    result_.pose = workload.pose != nullptr;
    if (workload.pose) result_.clip = workload.pose->label;
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
      result_.CountError(frame.status);
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
      result_.CountError(tick.status, std::max<std::size_t>(tick.characters.size(), 1));
      return;
    }
    std::size_t failed = 0;
    for (const client::FrameResult& c : tick.characters) {
      if (!c.status.ok()) ++failed, result_.CountError(c.status);
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
      const bool passthrough = config_.backend == "passthrough";
      if (w.pose && !passthrough) {  // one instance: a pose is one character's
        const PoseAnswer pose{frame.frame, frame.encoding, frame.bounds[k],
                              positions,   normals,        tangents};
        if (!(PoseAnswerError(w, pose) <= 1)) return false;  // NaN fails
        continue;
      }
      if (w.tangents && !TangentsMatch(frame, k, tangents, w)) return false;
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
    result_.CountError(status);
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

// A stream's client: its own channel, the meshes it may upload again where a replica lacks
// one, and its region (RunConfig::shared_memory).
class StreamClient {
 public:
  StreamClient(const RunConfig& config, const std::vector<UploadedMesh>& meshes, int connection)
      : client_(client::MakeChannel(config.target, config.channel, connection), config.limits) {
    for (const UploadedMesh& m : meshes) {
      client_.Remember(m.mesh_id, m.workload->arrays, {.rest_encoding = m.workload->rest_encoding});
    }
    region_.emplace(config, *meshes.front().workload, client_);
  }
  client::SkinClient& client() { return client_; }
  const StreamRegion& region() const { return *region_; }

 private:
  client::SkinClient client_;
  std::optional<StreamRegion> region_;  // unregistered before the client goes
};

// One phase of a closed loop: counts its measured sends and says whether an answer (or a
// send) now is measured: all of a measured phase's in frame-count runs, those after the
// warm-up in time-bounded ones.
struct Phase {
  bool measured_phase;
  bool count_by_time;
  Recorder& recorder;
  uint64_t measured_sent = 0;

  bool Measured() const { return measured_phase && (!count_by_time || recorder.Measuring()); }
};

// Runs a closed loop's phases. Time-bounded: one until `stop`, counting the answers that
// arrive after the warm-up. Frame-count: unmeasured units until `warm`, then exactly
// `config.frames` measured ones numbered after them. `stream(phase, until, first, count,
// &sent)` streams units [first, first + count) until `until` and returns its status.
template <typename StreamPhase>
void RunClosedLoop(const RunConfig& config, const std::atomic<bool>& stop,
                   const std::atomic<bool>& warm, Recorder& recorder, StreamPhase stream) {
  const auto run = [&](bool measured_phase, const std::atomic<bool>* until, uint64_t first,
                       uint64_t count, uint64_t* sent) {
    Phase phase{measured_phase, config.frames == 0, recorder};
    const Status status = stream(phase, until, first, count, sent);
    if (measured_phase) recorder.AddSentAndDropped(phase.measured_sent, 0);
    if (!status.ok()) recorder.RecordStreamError(status);
    return status.ok();
  };
  constexpr uint64_t kEndless = UINT64_MAX / 2;
  if (config.frames == 0) {
    run(true, &stop, 0, kEndless, nullptr);
    return;
  }
  uint64_t warmup_sent = 0;
  if (config.warmup_seconds > 0 && !run(false, &warm, 0, kEndless, &warmup_sent)) return;
  recorder.StartMeasuring(Clock::now());
  run(true, nullptr, warmup_sent, config.frames, nullptr);
}

// Keeps `window` frames in flight (StreamFrames), in the phases of RunClosedLoop.
void ClosedLoopStream(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                      int connection, const std::atomic<bool>& stop, const std::atomic<bool>& warm,
                      Recorder& recorder) {
  const Workload& workload = *meshes.front().workload;
  StreamClient stream_client(config, meshes, connection);
  const StreamRegion& region = stream_client.region();
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  FramePalette palette(workload, config.instances);
  client::StreamOptions options{.mesh_id = meshes.front().mesh_id,
                                .backend = config.backend,
                                .want_normals = workload.normals,
                                .want_tangents = workload.tangents,
                                .method = workload.method,
                                .encoding = config.encoding,
                                .instances = config.instances,
                                .output = region.output(),
                                .early_parts = config.early_parts,
                                .window = config.window};
  // Morph weights: a single instance's straight from the workload, a crowd's per instance.
  FrameMorph morph(workload, config.instances);
  if (!workload.morph_weights.empty() && config.instances <= 1) {
    options.morph_weights = [&](uint64_t f) { return workload.Morph(f); };
  } else if (!workload.morph_weights.empty()) {
    options.instance_morph_weights = [&](uint64_t f) { return morph(f); };
  }
  // --animate: frame f's pose instead of its palette (the palette source is not asked then).
  std::optional<FramePose> pose;
  if (workload.pose) pose.emplace(*workload.pose);
  RunClosedLoop(config, stop, warm, recorder,
                [&](Phase& phase, const std::atomic<bool>* until, uint64_t first, uint64_t count,
                    uint64_t* sent) {
                  options.stop = until;
                  options.first_frame = first;
                  options.frames = count;
                  if (pose) {
                    options.pose = [&](uint64_t f) {
                      if (phase.Measured()) ++phase.measured_sent;
                      return (*pose)(f);
                    };
                  }
                  client::StreamSummary summary;
                  const Status status = client::StreamFrames(
                      stream_client.client(), options,
                      [&](uint64_t f) {
                        if (phase.Measured()) ++phase.measured_sent;
                        return palette(f);
                      },
                      [&](client::FrameResult& r, std::chrono::nanoseconds latency) {
                        recorder.Record(r, latency.count() / 1e6, false, phase.Measured());
                      },
                      &summary);
                  if (sent != nullptr) *sent = summary.sent;
                  return status;
                });
}

// ClosedLoopStream for ticks: `window` ticks in flight (StreamTicks), each of every mesh's
// character, counted as ClosedLoopStream counts frames.
void ClosedLoopTickStream(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                          int connection, const std::atomic<bool>& stop,
                          const std::atomic<bool>& warm, Recorder& recorder) {
  StreamClient stream_client(config, meshes, connection);
  const StreamRegion& region = stream_client.region();
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  TickFiller fill(meshes, {config.backend, config.encoding, config.instances}, region.output(),
                  region.character_stride());
  client::TickStreamOptions options{.window = config.window,
                                    .region_stride = region.output().stride};
  RunClosedLoop(config, stop, warm, recorder,
                [&](Phase& phase, const std::atomic<bool>* until, uint64_t first, uint64_t count,
                    uint64_t* sent) {
                  options.stop = until;
                  options.first_tick = first;
                  options.ticks = count;
                  client::TickStreamSummary summary;
                  const Status status = client::StreamTicks(
                      stream_client.client(), options,
                      [&](uint64_t f, client::Tick* tick) {
                        if (phase.Measured()) ++phase.measured_sent;
                        fill(f, tick);
                      },
                      [&](client::TickResult& r, std::chrono::nanoseconds latency) {
                        recorder.RecordTick(r, latency.count() / 1e6, false, phase.Measured());
                      },
                      &summary);
                  if (sent != nullptr) *sent = summary.sent;
                  return status;
                });
}

// What differs between frames and ticks in an open loop: unit k's request in its window slot
// (its range of the region), and the gathering and recording of the oldest unit's answer.
class OpenLoopUnits {
 public:
  virtual ~OpenLoopUnits() = default;
  // Valid until the next call.
  virtual const v1::SkinRequest& Prepare(uint64_t k, std::size_t slot) = 0;
  // The answer of the unit in `slot` begins; AddPart is true once it is complete.
  virtual void BeginAnswer(std::size_t slot) = 0;
  virtual bool AddPart(const grpc::ByteBuffer& bytes) = 0;
  // The meshes the complete answer says the server does not hold (NOT_FOUND).
  virtual void LostMeshes(std::set<std::string>* lost) const = 0;
  // Records the complete answer and ends it.
  virtual void Record(Recorder& recorder, double latency_ms, bool late, bool measured,
                      double lag_ms) = 0;
};

class OpenLoopFrames final : public OpenLoopUnits {
 public:
  OpenLoopFrames(const RunConfig& config, const UploadedMesh& mesh,
                 const client::RegionOutput& output)
      : config_(config),
        workload_(*mesh.workload),
        output_(output),
        palette_(workload_, config.instances),
        morph_(workload_, config.instances) {
    if (workload_.pose) pose_.emplace(*workload_.pose);
    // Reused: only the frame number, the palette (or pose) and the slot's offset change.
    request_.set_mesh_id(mesh.mesh_id);
    request_.set_backend(config.backend);
    request_.set_want_normals(workload_.normals);
    request_.set_want_tangents(workload_.tangents);
    request_.set_encoding(static_cast<v1::Encoding>(config.encoding));
    request_.set_instances(config.instances);
    request_.set_pack_instances(true);  // FrameAssembler takes packed parts
    request_.set_method(wire::ToWire(workload_.method));
    if (output.enabled()) request_.mutable_output()->set_region(output.name);
    request_.set_early_parts(config.early_parts);
  }

  const v1::SkinRequest& Prepare(uint64_t k, std::size_t slot) override {
    if (output_.enabled()) request_.mutable_output()->set_offset(slot * output_.stride);
    request_.set_frame(k);
    if (pose_) {
      client::PoseToWire((*pose_)(k), &request_);
    } else {
      wire::EncodeFloats(palette_(k), request_.mutable_palette());
    }
    if (!workload_.morph_weights.empty() && config_.instances <= 1) {
      wire::MorphWeightsToWire(workload_.Morph(k), &request_);
    } else if (!workload_.morph_weights.empty()) {
      wire::InstanceMorphWeightsToWire(morph_(k), &request_);
    }
    return request_;
  }
  void BeginAnswer(std::size_t) override { assembler_.emplace(&output_); }
  bool AddPart(const grpc::ByteBuffer& bytes) override {
    return assembler_->Add(bytes, &part_, &result_);
  }
  void LostMeshes(std::set<std::string>* lost) const override {
    if (result_.status.code() == StatusCode::kNotFound) lost->insert(request_.mesh_id());
  }
  void Record(Recorder& recorder, double latency_ms, bool late, bool measured,
              double lag_ms) override {
    recorder.Record(result_, latency_ms, late, measured, lag_ms);
    assembler_.reset();
  }

 private:
  const RunConfig& config_;
  const Workload& workload_;
  const client::RegionOutput& output_;
  FramePalette palette_;
  FrameMorph morph_;
  std::optional<FramePose> pose_;  // --animate
  v1::SkinRequest request_;
  // One part reader and one result for the whole run (their buffers are reused).
  wire::RawPart part_;
  std::optional<client::FrameAssembler> assembler_;
  client::FrameResult result_;
};

// Each unit a tick of every mesh's character, its slot of the region holding them all.
class OpenLoopTicks final : public OpenLoopUnits {
 public:
  OpenLoopTicks(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                const StreamRegion& region)
      : output_(region.output()),
        fill_(meshes, {config.backend, config.encoding, config.instances}, region.output(),
              region.character_stride()),
        ticks_(static_cast<std::size_t>(std::max(config.window, 1))) {}

  const v1::SkinRequest& Prepare(uint64_t k, std::size_t slot) override {
    // The slot is this tick's until its answer: the reader reads it then.
    client::Tick& tick = ticks_[slot];
    tick.Clear();
    tick.set_frame(k);
    fill_(k, &tick);
    tick.ToWire(&request_, slot * output_.stride);
    return request_;
  }
  void BeginAnswer(std::size_t slot) override {
    answering_ = slot;
    assembler_.emplace(ticks_[slot], &result_);
  }
  bool AddPart(const grpc::ByteBuffer& bytes) override { return assembler_->Add(bytes, &part_); }
  void LostMeshes(std::set<std::string>* lost) const override {
    const client::Tick& tick = ticks_[answering_];
    for (std::size_t i = 0; i < tick.size() && i < result_.characters.size(); ++i) {
      if (result_.characters[i].status.code() == StatusCode::kNotFound) {
        lost->insert(tick.character(i).mesh_id);
      }
    }
  }
  void Record(Recorder& recorder, double latency_ms, bool late, bool measured,
              double lag_ms) override {
    recorder.RecordTick(result_, latency_ms, late, measured, lag_ms);
    assembler_.reset();
  }

 private:
  const client::RegionOutput& output_;
  TickFiller fill_;
  std::vector<client::Tick> ticks_;  // the tick sent in each slot
  std::size_t answering_ = 0;        // the slot whose answer is being gathered
  v1::SkinRequest request_;
  wire::RawPart part_;
  std::optional<client::TickAssembler> assembler_;
  client::TickResult result_;
};

// One open-loop stream (OpenLoopStream): its schedule, and the ring of units in flight that
// the sending thread and the reader share.
class OpenLoop {
 public:
  OpenLoop(const RunConfig& config, int stream_index, Clock::time_point start,
           Clock::time_point end, client::SkinClient& client, OpenLoopUnits& units,
           Recorder& recorder)
      : config_(config),
        start_(start),
        end_(end),
        client_(client),
        units_(units),
        recorder_(recorder),
        stream_(config.frame_socket.empty() ? OpenGrpcStream(client)
                                            : OpenFrameSocketStream(config.frame_socket)),
        watchdog_([s = stream_.get()] { s->Cancel(); }, config.limits.stream_idle),
        closed_(config.rate <= 0),
        period_(closed_ ? Clock::duration::max()
                        : std::chrono::duration_cast<Clock::duration>(
                              std::chrono::duration<double>(1.0 / config.rate))),
        warmup_frames_(config.frames > 0
                           ? static_cast<uint64_t>(std::ceil(config.warmup_seconds * config.rate))
                           : 0),
        last_frame_(config.frames > 0 ? warmup_frames_ + config.frames : UINT64_MAX),
        schedule_(config.arrivals, config.rate, stream_index, config.streams, config.arrivals_seed),
        ring_(static_cast<std::size_t>(std::max(config.window, 1))) {}

  void Run(const std::vector<UploadedMesh>& meshes, const std::atomic<bool>& stop) {
    ProbeMeshes(meshes);
    if (closed_) {
      due_ = Clock::now();
    } else {
      SkipPassed();
    }
    std::thread reader([&] { Read(); });
    Send(stop);
    stream_->WritesDone();
    reader.join();
    Finish();
  }

 private:
  struct Scheduled {
    Clock::time_point due, sent;
    bool measured;
    int uploads_before;  // re-uploads done when it was sent
  };

  void ProbeMeshes(const std::vector<UploadedMesh>& meshes);
  // Frame k's time; frame-count runs start measuring at the first measured frame's. Closed
  // loop: none (WaitForSlot sets it when a slot frees).
  void ScheduleNext() {
    if (closed_) return;
    due_ = start_ + std::chrono::duration_cast<Clock::duration>(
                        std::chrono::duration<double>(schedule_.Next()));
    if (config_.frames > 0 && k_ == warmup_frames_) recorder_.StartMeasuring(due_);
  }
  bool Measured() const {
    return config_.frames > 0 ? k_ >= warmup_frames_ : recorder_.Measuring(due_);
  }
  void SkipPassed();
  // Closed loop: waits until fewer than `window` frames are in flight (or the stream ended,
  // or its time is up) and makes now the next frame's time; false: send no more.
  bool WaitForSlot(const std::atomic<bool>& stop);
  void Read();
  void Send(const std::atomic<bool>& stop);
  bool TakeSlot(std::size_t* slot, bool counted, Clock::time_point sent_at);
  void ReuploadLost(const Scheduled& frame);
  void Finish();

  const RunConfig& config_;
  const Clock::time_point start_, end_;
  client::SkinClient& client_;
  OpenLoopUnits& units_;
  Recorder& recorder_;
  std::unique_ptr<UnitStream> stream_;  // StreamSkin, or the frame socket
  client::IdleWatchdog watchdog_;
  // No --rate (the socket plane; StreamSkin's closed loop is ClosedLoopStream): `window`
  // frames in flight, the next sent as an answer frees a slot, its latency counted from then.
  const bool closed_;
  const Clock::duration period_;
  const uint64_t warmup_frames_, last_frame_;
  ArrivalSchedule schedule_;
  uint64_t k_ = 0;
  Clock::time_point due_;
  uint64_t sent_ = 0, dropped_ = 0;  // measured frames only
  std::mutex mutex_;
  // Sent, unanswered, oldest first: a ring of `window` slots (never more are in flight).
  std::vector<Scheduled> ring_;
  std::size_t ring_head_ = 0, in_flight_ = 0;
  std::condition_variable slot_freed_;  // closed loop: an answer freed a slot, or reading ended
  bool reading_ended_ = false;
  std::set<std::string> lost_;  // the answer's meshes the server lost
  int reuploads_ = 0;           // re-upload attempts done (under mutex_: TakeSlot reads it)
  int reuploads_in_a_row_ = 0;  // without an answer that found its meshes
};

// Before the schedule starts, make sure this stream's replica holds the mesh: one frame
// outside the schedule, re-uploading on NOT_FOUND (round_robin may place the upload on
// another replica, hence the retries). It asks for `passthrough`, so that it never counts
// as a frame of the backend under test on the server either. Ticks: each mesh's.
void OpenLoop::ProbeMeshes(const std::vector<UploadedMesh>& meshes) {
  for (std::size_t m = 0, attempt = 0; m < meshes.size() && attempt < 8; ++attempt) {
    v1::SkinRequest probe;
    probe.set_mesh_id(meshes[m].mesh_id);
    probe.set_backend("passthrough");
    probe.set_frame(UINT64_MAX);
    // one instance, float32
    probe.set_palette(wire::EncodeFloats(meshes[m].workload->Palette(0)));
    if (!stream_->Write(probe)) break;
    client::FrameResult result;
    client::FrameAssembler assembler;
    wire::RawPart part;
    grpc::ByteBuffer bytes;
    bool complete = false;
    watchdog_.Awaiting(true);
    while (!complete && stream_->Read(&bytes)) complete = assembler.Add(bytes, &part, &result);
    watchdog_.Awaiting(false);
    if (!complete) break;
    if (result.status.code() != StatusCode::kNotFound) {
      ++m, attempt = 0;
    } else if (!client_.Reupload(meshes[m].mesh_id).ok()) {
      break;
    }
  }
}

// The schedule began at `start` for every stream alike: frames whose time passed while
// this one opened were not delivered.
void OpenLoop::SkipPassed() {
  const Clock::time_point ready = Clock::now();
  for (ScheduleNext(); k_ < last_frame_ && due_ + period_ < ready && due_ < end_; ScheduleNext()) {
    dropped_ += Measured();
    ++k_;
  }
}

// The reader thread: answers come in order, each the oldest unit's in flight.
void OpenLoop::Read() {
  grpc::ByteBuffer bytes;
  bool answering = false;
  while (stream_->Read(&bytes)) {
    watchdog_.Answered();
    if (!answering) {
      std::lock_guard lock(mutex_);
      units_.BeginAnswer(ring_head_);
      answering = true;
    }
    if (!units_.AddPart(bytes)) continue;
    const Clock::time_point answered = Clock::now();
    Scheduled frame;
    {
      std::lock_guard lock(mutex_);
      frame = ring_[ring_head_];
    }
    const auto latency = answered - frame.due;
    const double latency_ms = std::chrono::duration<double, std::milli>(latency).count();
    const double lag_ms = std::chrono::duration<double, std::milli>(frame.sent - frame.due).count();
    lost_.clear();
    units_.LostMeshes(&lost_);
    units_.Record(recorder_, latency_ms, latency > period_, frame.measured, lag_ms);
    answering = false;
    {  // only now may the frame's slot (and its range of a region) take the next frame
      std::lock_guard lock(mutex_);
      ring_head_ = (ring_head_ + 1) % ring_.size();
      --in_flight_;
      watchdog_.Awaiting(in_flight_ > 0);
    }
    slot_freed_.notify_one();
    ReuploadLost(frame);
  }
  {
    std::lock_guard lock(mutex_);
    reading_ended_ = true;
  }
  slot_freed_.notify_one();
}

bool OpenLoop::WaitForSlot(const std::atomic<bool>& stop) {
  std::unique_lock lock(mutex_);
  // Woken by answers; the timeout only bounds how late `stop` and the run's end are seen.
  while (in_flight_ >= ring_.size() && !reading_ended_ && !stop.load() && Clock::now() < end_) {
    slot_freed_.wait_for(lock, std::chrono::milliseconds(20));
  }
  due_ = Clock::now();
  return in_flight_ < ring_.size() && !reading_ended_ && !stop.load() && due_ < end_;
}

// A mesh the server lost mid-run (evicted for another, deleted, a replica without it) goes
// again, so that the schedule's later frames find it; the frames that met its absence stay
// failed (NOT_FOUND) in the report. Once per loss: frames sent before the last re-upload were
// on their way already. At most kMaxReuploadsInARow attempts without an answer between that
// found its meshes (then the rest fail NOT_FOUND, as without re-uploads).
void OpenLoop::ReuploadLost(const Scheduled& frame) {
  if (lost_.empty()) {
    reuploads_in_a_row_ = 0;
    return;
  }
  {
    std::lock_guard lock(mutex_);
    if (frame.uploads_before < reuploads_ || reuploads_in_a_row_ >= kMaxReuploadsInARow) return;
  }
  ++reuploads_in_a_row_;
  // One that fails leaves the next frames NOT_FOUND, which the report counts.
  for (const std::string& mesh_id : lost_) (void)client_.Reupload(mesh_id);
  // Only now: the frames sent while the mesh was on its way may still meet its absence.
  std::lock_guard lock(mutex_);
  ++reuploads_;
}

// Takes a slot for frame k, or drops it (false) when `window` frames are in flight.
bool OpenLoop::TakeSlot(std::size_t* slot, bool counted, Clock::time_point sent_at) {
  std::lock_guard lock(mutex_);
  if (in_flight_ >= ring_.size()) {
    dropped_ += counted;
    return false;
  }
  // Frames in flight take the ring's slots in turn: each its own range of the region.
  *slot = (ring_head_ + in_flight_++) % ring_.size();
  ring_[*slot] = {due_, sent_at, counted, reuploads_};
  watchdog_.Awaiting(true);
  return true;
}

// Sends each frame at its time; the gaps between measured sends feed the run's send timing.
void OpenLoop::Send(const std::atomic<bool>& stop) {
  uint64_t late_sends = 0, gaps = 0;
  double gap_ms_sum = 0, gap_ms_sq_sum = 0;
  Clock::time_point previous_send{};  // of the last measured frame sent, if it was the last
  for (; k_ < last_frame_ && due_ < end_ && !stop.load(); ++k_, ScheduleNext()) {
    if (closed_) {
      if (!WaitForSlot(stop)) break;
    } else {
      std::this_thread::sleep_until(due_);
    }
    if (stop.load()) break;
    const bool counted = Measured();
    const Clock::time_point sent_at = Clock::now();
    std::size_t slot = 0;
    if (!TakeSlot(&slot, counted, sent_at)) {
      previous_send = {};
      continue;
    }
    const v1::SkinRequest& request = units_.Prepare(k_, slot);
    if (counted) {
      ++sent_;
      late_sends += sent_at - due_ > std::chrono::duration<double, std::milli>(kLateSendMs);
      if (previous_send != Clock::time_point{}) {
        const double gap =
            std::chrono::duration<double, std::milli>(sent_at - previous_send).count();
        ++gaps;
        gap_ms_sum += gap;
        gap_ms_sq_sum += gap * gap;
      }
    }
    previous_send = counted ? sent_at : Clock::time_point{};
    if (!stream_->Write(request)) break;
  }
  recorder_.AddSendTiming(late_sends, gaps, gap_ms_sum, gap_ms_sq_sum);
}

void OpenLoop::Finish() {
  Status status = stream_->Finish();
  if (watchdog_.fired()) {
    status = DeadlineExceeded(
        fmt::format("no answer for {:.1f} s with frames in flight (--stream-idle-seconds)",
                    watchdog_.limit().count() / 1000.0));
  }
  {
    std::lock_guard lock(mutex_);
    // Sent but never answered: failed, not lost.
    for (std::size_t i = 0; i < in_flight_; ++i) {
      recorder_.RecordStreamError(status.ok() ? Internal("unanswered") : status);
    }
  }
  if (!status.ok() && in_flight_ == 0) recorder_.RecordStreamError(status);
  recorder_.AddSentAndDropped(sent_, dropped_);
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
// character, its slot of the region holding them all. Without a rate (the frame socket's
// closed loop, time-bounded) each frame goes as soon as fewer than `window` are in flight.
void OpenLoopStream(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                    int stream_index, int connection, const std::atomic<bool>& stop,
                    Clock::time_point start, Clock::time_point end, Recorder& recorder) {
  StreamClient stream_client(config, meshes, connection);
  const StreamRegion& region = stream_client.region();
  if (!region.status().ok()) {
    recorder.RecordStreamError(region.status());
    return;
  }
  std::unique_ptr<OpenLoopUnits> units;
  if (config.characters_per_tick > 0) {
    units = std::make_unique<OpenLoopTicks>(config, meshes, region);
  } else {
    units = std::make_unique<OpenLoopFrames>(config, meshes.front(), region.output());
  }
  OpenLoop(config, stream_index, start, end, stream_client.client(), *units, recorder)
      .Run(meshes, stop);
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
      if (config.rate > 0 || !config.frame_socket.empty()) {  // the socket's closed loop too
        OpenLoopStream(config, meshes, s, connection, stop, start,
                       by_frames ? Clock::time_point::max() : start + total, recorder);
      } else if (config.characters_per_tick > 0) {
        ClosedLoopTickStream(config, meshes, connection, stop, warm, recorder);
      } else {
        ClosedLoopStream(config, meshes, connection, stop, warm, recorder);
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
