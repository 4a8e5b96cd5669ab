// Conversions between wire messages (skinserve.v1) and the model's types, written once for
// the server and the clients. Nothing here decides policy: the engine validates, this only
// converts, and names the wire field when bytes or enum values are malformed.
#pragma once

#include <grpcpp/support/status.h>

#include <span>
#include <string>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/quantized_rest.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::wire {

// The model's codes are the gRPC codes of the same name; both directions keep the message.
grpc::Status ToGrpc(const Status& status);
Status FromGrpc(const grpc::Status& status);

// float32 values as the wire's little-endian bytes (a palette), reusing `bytes`' capacity.
void EncodeFloats(std::span<const float> values, std::string* bytes);
std::string EncodeFloats(std::span<const float> values);
// Little-endian bytes to values; INVALID_ARGUMENT naming `field` if the length is not a
// whole number of values.
Status DecodeFloats(const std::string& bytes, const char* field, std::vector<float>* out);

// The request's method; INVALID_ARGUMENT naming the field for a value this side does not
// know (proto3 enums carry unknown numbers through).
Result<SkinningMethod> FromWire(v1::SkinningMethod method);
v1::SkinningMethod ToWire(SkinningMethod method);

// An upload's rest encoding (MeshHeader.rest_encoding); INVALID_ARGUMENT naming the field
// and the known values.
Result<RestEncoding> FromWire(v1::RestEncoding encoding);
v1::RestEncoding ToWire(RestEncoding encoding);

// The request's encoding; INVALID_ARGUMENT naming the field and the known values.
Result<VertexEncoding> FromWire(v1::Encoding encoding);
v1::Encoding ToWire(VertexEncoding encoding);

// A frame's sparse morph weights (SkinRequest.morph_targets and .morph_weights), into
// `out` (its capacity reused). INVALID_ARGUMENT naming the fields when their lengths
// differ (the one rule of the wire's own); how many there may be is the request reader's
// to check before the parse (skin_request_reader.h), the values the engine's
// (ValidateMorphWeights).
Status MorphWeightsFromWire(const v1::SkinRequest& request, std::vector<MorphWeight>* out);
// Sets the request's morph fields to `weights` (all of them: zeros are sent as given).
void MorphWeightsToWire(std::span<const MorphWeight> weights, v1::SkinRequest* request);
// A crowd's per-instance weights (SkinRequest.instance_morph_weights): all instances' entries
// back to back in `flat` (its capacity reused) and one view per instance in `instances`;
// both empty when the field is. INVALID_ARGUMENT naming the entry when its lengths differ;
// the entry count against the batch, the field set together with morph_weights and the
// values are the engine's to check (Engine::Submit), the lengths' limits the reader's.
Status InstanceMorphWeightsFromWire(const v1::SkinRequest& request, std::vector<MorphWeight>* flat,
                                    std::vector<std::span<const MorphWeight>>* instances);
// Sets SkinRequest.instance_morph_weights to one entry per element of `instances`.
void InstanceMorphWeightsToWire(std::span<const std::vector<MorphWeight>> instances,
                                v1::SkinRequest* request);

Bounds FromWire(const v1::Bounds& bounds);
void ToWire(const Bounds& bounds, v1::Bounds* wire);

}  // namespace skinserve::wire
