// The engine's reports as wire messages (the model's conversions, shared with the clients,
// are in skinserve/wire/conversions.h).
#pragma once

#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.pb.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::server {

using wire::DecodeFloats;
using wire::FromWire;
using wire::InstanceMorphWeightsFromWire;
using wire::MorphWeightsFromWire;
using wire::ToGrpc;
using wire::ToWire;

v1::MeshInfo ToWire(const MeshInfo& info);
v1::BackendInfo ToWire(const BackendInfo& info);

}  // namespace skinserve::server
