// The server's one ToWire home. The model's conversions (methods, encodings, bounds, morph
// weights) are written once in skinserve/wire/conversions.h, shared with the clients, and
// brought in here by name; below them, the messages only the server sends: the engine's
// reports, the server's own statistics and its shared-memory regions. Those cannot live in
// wire/, which sits below the server and beside the client library and so knows neither
// the engine's reports nor the server's snapshot: they live in this one file instead of
// beside each caller.
#pragma once

#include "observability/server_snapshot.h"
#include "shm/region_registry.h"
#include "skinserve/animation/animation_store.h"
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
// GetServerStats' answer: everything /metrics shows too (server_snapshot.h).
v1::ServerStats ToWire(const ServerSnapshot& snapshot);
void ToWire(const RegionInfo& info, v1::RegionInfo* wire);
void ToWire(const animation::SkeletonInfo& info, v1::SkeletonInfo* wire);
void ToWire(const animation::ClipInfo& info, v1::ClipInfo* wire);

}  // namespace skinserve::server
