#include "mesh_upload_reactor.h"

#include <spdlog/spdlog.h>

#include "engine_messages.h"

namespace skinserve::server {

MeshUploadReactor::MeshUploadReactor(Engine* engine, v1::MeshInfo* response)
    : assembly_(engine), response_(response) {
  if (engine == nullptr) {
    Finish(ToGrpc(Unavailable("the server is starting: backends are being built")));
    return;
  }
  StartRead(&message_);
}

void MeshUploadReactor::OnReadDone(bool ok) {
  if (!ok) {  // the client finished sending (or went away: then Finish goes nowhere)
    Finish(ToGrpc(Store()));
    return;
  }
  if (Status s = assembly_.Accept(message_); !s.ok()) {
    Finish(ToGrpc(s));  // drop everything received so far
    return;
  }
  StartRead(&message_);
}

Status MeshUploadReactor::Store() {
  auto info = assembly_.Store();
  if (!info.ok()) return info.status();
  *response_ = ToWire(*info);
  spdlog::info("mesh {} stored: {} vertices, {} influences, {} joints{}", info->id,
               info->vertex_count, info->influences, info->joint_count,
               info->already_stored ? " (already stored)" : "");
  return Status::Ok();
}

}  // namespace skinserve::server
