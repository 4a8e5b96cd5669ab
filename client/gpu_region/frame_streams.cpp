#include "frame_streams.h"

#include <fmt/format.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>

#include "skinserve/wire/conversions.h"

namespace skinserve::gpu_region {

Status StreamIntoRegion(v1::Skinning::Stub& stub, const StreamPlan& plan,
                        const std::function<Status(uint32_t, const v1::SkinResponse&)>& answered) {
  grpc::ClientContext context;
  auto stream = stub.StreamSkin(&context);
  v1::SkinRequest request;
  request.set_mesh_id(plan.mesh_id);
  request.set_backend(plan.backend);
  request.set_want_normals(plan.normals);
  request.set_encoding(wire::ToWire(plan.encoding));
  request.mutable_output()->set_region(plan.region);
  request.mutable_output()->set_gpu(plan.gpu);
  const auto send = [&](uint32_t frame) {
    request.set_frame(frame);
    request.set_palette(plan.palette(frame));
    request.clear_morph_targets();
    request.clear_morph_weights();
    if (plan.morph) {
      for (const MorphWeight& w : plan.morph(frame)) {
        request.add_morph_targets(w.target);
        request.add_morph_weights(w.weight);
      }
    }
    request.mutable_output()->set_offset((frame % plan.window) * plan.slot_bytes);
    request.mutable_output()->set_byte_size(plan.slot_bytes);
    return stream->Write(request);
  };
  uint32_t sent = 0;
  while (sent < std::min(plan.window, plan.frames) && send(sent)) ++sent;
  Status failed;
  v1::SkinResponse response;
  for (uint32_t done = 0; done < plan.frames && failed.ok(); ++done) {
    if (!stream->Read(&response)) break;
    if (response.has_error()) {
      failed = Status(static_cast<StatusCode>(response.error().code()),
                      fmt::format("frame {}: {}", response.frame(), response.error().message()));
      break;
    }
    failed = answered(static_cast<uint32_t>(response.frame()), response);
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
