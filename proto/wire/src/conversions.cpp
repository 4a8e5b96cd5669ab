#include "skinserve/wire/conversions.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cstring>

namespace skinserve::wire {

static_assert(std::endian::native == std::endian::little, "the wire is little-endian");

grpc::Status ToGrpc(const Status& status) {
  switch (status.code()) {
    case StatusCode::kOk:
      return grpc::Status::OK;
    case StatusCode::kInvalidArgument:
      return {grpc::StatusCode::INVALID_ARGUMENT, status.message()};
    case StatusCode::kNotFound:
      return {grpc::StatusCode::NOT_FOUND, status.message()};
    case StatusCode::kAlreadyExists:
      return {grpc::StatusCode::ALREADY_EXISTS, status.message()};
    case StatusCode::kResourceExhausted:
      return {grpc::StatusCode::RESOURCE_EXHAUSTED, status.message()};
    case StatusCode::kFailedPrecondition:
      return {grpc::StatusCode::FAILED_PRECONDITION, status.message()};
    case StatusCode::kUnavailable:
      return {grpc::StatusCode::UNAVAILABLE, status.message()};
    case StatusCode::kInternal:
      return {grpc::StatusCode::INTERNAL, status.message()};
    case StatusCode::kDeadlineExceeded:
      return {grpc::StatusCode::DEADLINE_EXCEEDED, status.message()};
    case StatusCode::kCancelled:
      return {grpc::StatusCode::CANCELLED, status.message()};
    case StatusCode::kPermissionDenied:
      return {grpc::StatusCode::PERMISSION_DENIED, status.message()};
    case StatusCode::kUnauthenticated:
      return {grpc::StatusCode::UNAUTHENTICATED, status.message()};
  }
  return {grpc::StatusCode::UNKNOWN, status.message()};
}

Status FromGrpc(const grpc::Status& status) {
  switch (status.error_code()) {
    case grpc::StatusCode::OK:
      return Status::Ok();
    case grpc::StatusCode::INVALID_ARGUMENT:
      return InvalidArgument(status.error_message());
    case grpc::StatusCode::NOT_FOUND:
      return NotFound(status.error_message());
    case grpc::StatusCode::ALREADY_EXISTS:
      return AlreadyExists(status.error_message());
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return ResourceExhausted(status.error_message());
    case grpc::StatusCode::FAILED_PRECONDITION:
      return FailedPrecondition(status.error_message());
    case grpc::StatusCode::UNAVAILABLE:
      return Unavailable(status.error_message());
    case grpc::StatusCode::INTERNAL:
      return Internal(status.error_message());
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return DeadlineExceeded(status.error_message());
    case grpc::StatusCode::CANCELLED:
      return {StatusCode::kCancelled, status.error_message()};
    case grpc::StatusCode::PERMISSION_DENIED:
      return {StatusCode::kPermissionDenied, status.error_message()};
    case grpc::StatusCode::UNAUTHENTICATED:
      return {StatusCode::kUnauthenticated, status.error_message()};
    default:
      return Internal(fmt::format("gRPC status {}: {}", static_cast<int>(status.error_code()),
                                  status.error_message()));
  }
}

void EncodeFloats(std::span<const float> values, std::string* bytes) {
  bytes->resize(values.size_bytes());
  if (!values.empty()) std::memcpy(bytes->data(), values.data(), values.size_bytes());
}

std::string EncodeFloats(std::span<const float> values) {
  std::string bytes;
  EncodeFloats(values, &bytes);
  return bytes;
}

Status DecodeFloats(const std::string& bytes, const char* field, std::vector<float>* out) {
  if (bytes.size() % sizeof(float) != 0) {
    return InvalidArgument(fmt::format("{} holds {} bytes, not a whole number of float32 values",
                                       field, bytes.size()));
  }
  out->resize(bytes.size() / sizeof(float));
  if (!bytes.empty()) std::memcpy(out->data(), bytes.data(), bytes.size());
  return Status::Ok();
}

Result<SkinningMethod> FromWire(v1::SkinningMethod method) {
  switch (method) {
    case v1::SKINNING_METHOD_LINEAR:
      return SkinningMethod::kLinear;
    case v1::SKINNING_METHOD_DUAL_QUATERNION:
      return SkinningMethod::kDualQuaternion;
    default:
      return InvalidArgument(
          fmt::format("method = {} is unknown; known: 0 (linear), 1 (dual-quaternion)",
                      static_cast<int>(method)));
  }
}

v1::SkinningMethod ToWire(SkinningMethod method) {
  return method == SkinningMethod::kDualQuaternion ? v1::SKINNING_METHOD_DUAL_QUATERNION
                                                   : v1::SKINNING_METHOD_LINEAR;
}

Result<RestEncoding> FromWire(v1::RestEncoding encoding) {
  switch (encoding) {
    case v1::REST_ENCODING_FLOAT32:
      return RestEncoding::kFloat32;
    case v1::REST_ENCODING_QUANTIZED16:
      return RestEncoding::kQuantized16;
    case v1::REST_ENCODING_QUANTIZED8_WEIGHTS:
      return RestEncoding::kQuantized8Weights;
    default:
      return InvalidArgument(
          fmt::format("header.rest_encoding = {} is unknown; known: 0 (float32), 1 (quantized16), "
                      "2 (quantized8-weights)",
                      static_cast<int>(encoding)));
  }
}

v1::RestEncoding ToWire(RestEncoding encoding) {
  switch (encoding) {
    case RestEncoding::kQuantized16:
      return v1::REST_ENCODING_QUANTIZED16;
    case RestEncoding::kQuantized8Weights:
      return v1::REST_ENCODING_QUANTIZED8_WEIGHTS;
    case RestEncoding::kFloat32:
      break;
  }
  return v1::REST_ENCODING_FLOAT32;
}

Result<VertexEncoding> FromWire(v1::Encoding encoding) {
  // The wire's values are the encodings' own (EncodingDescription, in their order).
  const auto value = static_cast<VertexEncoding>(encoding);
  if (encoding >= 0 && DescribeEncoding(value) != nullptr) return value;
  std::string known;
  for (const EncodingDescription& e : Encodings()) {
    known += fmt::format("{}{} ({})", known.empty() ? "" : ", ", e.name, static_cast<int>(e.id));
  }
  return InvalidArgument(
      fmt::format("encoding = {} is unknown; known: {}", static_cast<int>(encoding), known));
}

v1::Encoding ToWire(VertexEncoding encoding) { return static_cast<v1::Encoding>(encoding); }

Bounds FromWire(const v1::Bounds& b) {
  return {{b.min_x(), b.min_y(), b.min_z()}, {b.max_x(), b.max_y(), b.max_z()}};
}

void ToWire(const Bounds& b, v1::Bounds* wire) {
  wire->set_min_x(b.min[0]);
  wire->set_min_y(b.min[1]);
  wire->set_min_z(b.min[2]);
  wire->set_max_x(b.max[0]);
  wire->set_max_y(b.max[1]);
  wire->set_max_z(b.max[2]);
}

Status MorphWeightsFromWire(const v1::SkinRequest& request, std::vector<MorphWeight>* out) {
  const int targets = request.morph_targets_size(), weights = request.morph_weights_size();
  if (targets != weights) {
    return InvalidArgument(
        fmt::format("morph_targets holds {} entries but morph_weights {}; they pair up one to one",
                    targets, weights));
  }
  out->resize(static_cast<std::size_t>(targets));
  for (int i = 0; i < targets; ++i) {
    (*out)[i] = {request.morph_targets(i), request.morph_weights(i)};
  }
  return Status::Ok();
}

Status InstanceMorphWeightsFromWire(const v1::SkinRequest& request, std::vector<MorphWeight>* flat,
                                    std::vector<std::span<const MorphWeight>>* instances) {
  instances->clear();
  const int entries = request.instance_morph_weights_size();
  if (entries == 0) return Status::Ok();
  std::size_t total = 0;
  for (int k = 0; k < entries; ++k) {
    const v1::MorphWeights& w = request.instance_morph_weights(k);
    if (w.targets_size() != w.weights_size()) {
      return InvalidArgument(fmt::format(
          "instance_morph_weights[{}]: targets holds {} entries but weights {}; they pair up one "
          "to one",
          k, w.targets_size(), w.weights_size()));
    }
    total += static_cast<std::size_t>(w.targets_size());
  }
  flat->resize(total);  // sized once: the spans below point into it
  std::size_t at = 0;
  for (int k = 0; k < entries; ++k) {
    const v1::MorphWeights& w = request.instance_morph_weights(k);
    const std::size_t begin = at;
    for (int i = 0; i < w.targets_size(); ++i) (*flat)[at++] = {w.targets(i), w.weights(i)};
    instances->push_back(std::span<const MorphWeight>(*flat).subspan(begin, at - begin));
  }
  return Status::Ok();
}

void InstanceMorphWeightsToWire(std::span<const std::vector<MorphWeight>> instances,
                                v1::SkinRequest* request) {
  request->clear_instance_morph_weights();
  for (const std::vector<MorphWeight>& weights : instances) {
    v1::MorphWeights* wire = request->add_instance_morph_weights();
    for (const MorphWeight& w : weights) {
      wire->add_targets(w.target);
      wire->add_weights(w.weight);
    }
  }
}

void MorphWeightsToWire(std::span<const MorphWeight> weights, v1::SkinRequest* request) {
  request->clear_morph_targets();
  request->clear_morph_weights();
  for (const MorphWeight& w : weights) {
    request->add_morph_targets(w.target);
    request->add_morph_weights(w.weight);
  }
}

}  // namespace skinserve::wire
