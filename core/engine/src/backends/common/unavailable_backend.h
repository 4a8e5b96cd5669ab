// A backend that cannot run on this machine: listed with its reason, refusing every call.
#pragma once

#include "skinserve/engine/backend.h"

namespace skinserve {

class UnavailableBackend final : public Backend {
 public:
  explicit UnavailableBackend(BackendInfo info) : info_(std::move(info)) {
    info_.available = false;
  }
  const BackendInfo& info() const override { return info_; }
  Result<std::unique_ptr<PreparedMesh>> Prepare(std::shared_ptr<const Mesh>) override {
    return Refusal();
  }
  Status Skin(const PreparedMesh&, const SkinFrame&) override { return Refusal(); }

 private:
  Status Refusal() const {
    return FailedPrecondition("backend '" + info_.id +
                              "' is unavailable: " + info_.unavailable_reason);
  }
  BackendInfo info_;
};

}  // namespace skinserve
