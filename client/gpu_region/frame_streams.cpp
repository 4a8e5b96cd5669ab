#include "frame_streams.h"

#include <fmt/format.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include "skinserve/wire/conversions.h"

namespace skinserve::gpu_region {

namespace {

// Character c's request of frame `frame` (its output in the frame's slot).
void FillCharacter(const StreamPlan& plan, uint32_t frame, uint32_t c, v1::SkinRequest* request) {
  request->set_mesh_id(plan.mesh_ids[c]);
  request->set_backend(plan.backend);
  request->set_want_normals(plan.normals);
  request->set_encoding(wire::ToWire(plan.encoding));
  request->set_palette(plan.palette(frame, c));
  request->clear_morph_targets();
  request->clear_morph_weights();
  if (plan.morph) {
    for (const MorphWeight& w : plan.morph(frame, c)) {
      request->add_morph_targets(w.target);
      request->add_morph_weights(w.weight);
    }
  }
  v1::OutputRegion* output = request->mutable_output();
  output->set_region(plan.region);
  output->set_gpu(plan.gpu);
  output->set_offset((frame % plan.window) * plan.tick_bytes() + c * plan.slot_bytes);
  output->set_byte_size(plan.slot_bytes);
}

Status ErrorOf(const v1::SkinResponse& response, const std::string& what) {
  return Status(static_cast<StatusCode>(response.error().code()),
                fmt::format("{}: {}", what, response.error().message()));
}

// The frame's failure, or a tick's first failed character's; OK if none.
Status FailureIn(const v1::SkinResponse& response) {
  const std::string frame = fmt::format("frame {}", response.frame());
  if (response.has_error()) return ErrorOf(response, frame);
  for (const v1::SkinResponse& c : response.tick().characters()) {
    if (c.has_error()) return ErrorOf(c, frame);
  }
  return Status::Ok();
}

}  // namespace

Status StreamIntoRegion(v1::Skinning::Stub& stub, const StreamPlan& plan,
                        const std::function<Status(uint32_t, const v1::SkinResponse&)>& answered) {
  grpc::ClientContext context;
  auto stream = stub.StreamSkin(&context);
  const auto characters = static_cast<uint32_t>(plan.mesh_ids.size());
  v1::SkinRequest request;
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  std::vector<Clock::time_point> sent_at(plan.frames);
  const auto send = [&](uint32_t frame) {
    if (plan.rate > 0) {
      std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                                std::chrono::duration<double>(frame / plan.rate)));
    }
    if (characters == 1) {
      FillCharacter(plan, frame, 0, &request);
    } else {
      while (request.characters_size() < static_cast<int>(characters)) request.add_characters();
      for (uint32_t c = 0; c < characters; ++c) {
        FillCharacter(plan, frame, c, request.mutable_characters(static_cast<int>(c)));
      }
    }
    request.set_frame(frame);
    sent_at[frame] = Clock::now();
    return stream->Write(request);
  };
  uint32_t sent = 0;
  while (sent < std::min(plan.window, plan.frames) && send(sent)) ++sent;
  Status failed;
  v1::SkinResponse response;
  for (uint32_t done = 0; done < plan.frames && failed.ok(); ++done) {
    if (!stream->Read(&response)) break;
    failed = FailureIn(response);
    if (!failed.ok()) break;
    const auto frame = static_cast<uint32_t>(response.frame());
    if (plan.latencies_ms != nullptr && frame < plan.frames) {
      plan.latencies_ms->push_back(
          std::chrono::duration<double, std::milli>(Clock::now() - sent_at[frame]).count());
    }
    failed = answered(frame, response);
    if (failed.ok() && sent < plan.frames && send(sent)) ++sent;
  }
  stream->WritesDone();
  if (!failed.ok()) {
    context.TryCancel();
    stream->Finish();
    return failed;
  }
  return wire::FromGrpc(stream->Finish());
}

}  // namespace skinserve::gpu_region
