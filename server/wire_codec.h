// Translation between wire messages and core types. Nothing here decides policy: the
// engine validates, this only converts (and names the wire field when bytes are malformed).
#pragma once

#include <grpcpp/grpcpp.h>

#include <span>
#include <string>
#include <vector>

#include "skinserve/core/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

grpc::Status ToGrpc(const Status& status);

// Little-endian bytes to values; INVALID_ARGUMENT naming `field` if the length is not a
// whole number of values.
Status DecodeFloats(const std::string& bytes, const char* field, std::vector<float>* out);

// The request's method; INVALID_ARGUMENT naming the field for a value this server does not
// know (proto3 enums carry unknown numbers through).
Result<SkinningMethod> FromWire(v1::SkinningMethod method);
v1::SkinningMethod ToWire(SkinningMethod method);

v1::MeshInfo ToWire(const MeshInfo& info);
v1::BackendInfo ToWire(const BackendInfo& info);
v1::ServerStats ToWire(const EngineStats& stats);

}  // namespace skinserve::server
