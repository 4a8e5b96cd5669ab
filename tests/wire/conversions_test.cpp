// proto/wire's conversions between wire messages and the model's types: every value of
// every enum the wire defines (read from the proto's own descriptors, so a value added to
// the proto without a conversion fails here) and every model value round trip; floats are
// the little-endian bytes the contract states, bit for bit; statuses keep code and message
// both ways; morph weights round trip through a serialized message; and every malformed
// message is refused with INVALID_ARGUMENT naming its field and the limit.
#include "skinserve/wire/conversions.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <set>

#include "expect_status.h"

namespace skinserve::testing {
namespace {

// Each model code and the gRPC code of the same name, written out here independently.
const std::map<StatusCode, grpc::StatusCode>& CodesOfTheSameName() {
  static const std::map<StatusCode, grpc::StatusCode> codes = {
      {StatusCode::kOk, grpc::StatusCode::OK},
      {StatusCode::kInvalidArgument, grpc::StatusCode::INVALID_ARGUMENT},
      {StatusCode::kNotFound, grpc::StatusCode::NOT_FOUND},
      {StatusCode::kAlreadyExists, grpc::StatusCode::ALREADY_EXISTS},
      {StatusCode::kResourceExhausted, grpc::StatusCode::RESOURCE_EXHAUSTED},
      {StatusCode::kFailedPrecondition, grpc::StatusCode::FAILED_PRECONDITION},
      {StatusCode::kUnavailable, grpc::StatusCode::UNAVAILABLE},
      {StatusCode::kInternal, grpc::StatusCode::INTERNAL},
      {StatusCode::kDeadlineExceeded, grpc::StatusCode::DEADLINE_EXCEEDED},
      {StatusCode::kCancelled, grpc::StatusCode::CANCELLED},
      {StatusCode::kPermissionDenied, grpc::StatusCode::PERMISSION_DENIED},
      {StatusCode::kUnauthenticated, grpc::StatusCode::UNAUTHENTICATED},
  };
  return codes;
}

TEST(ConversionsTest, EveryStatusCodeIsTheGrpcCodeOfItsNameBothWaysWithItsMessage) {
  // The table covers the model's enum: kUnauthenticated is its last value.
  ASSERT_EQ(CodesOfTheSameName().size(),
            static_cast<std::size_t>(StatusCode::kUnauthenticated) + 1);
  for (const auto& [code, grpc_code] : CodesOfTheSameName()) {
    const std::string message = code == StatusCode::kOk ? "" : "why it failed";
    const grpc::Status wire = wire::ToGrpc(Status(code, message));
    EXPECT_EQ(wire.error_code(), grpc_code) << static_cast<int>(code);
    EXPECT_EQ(wire.error_message(), message);
    const Status back = wire::FromGrpc(wire);
    EXPECT_EQ(back.code(), code);
    EXPECT_EQ(back.message(), message);
  }
  // A gRPC code the model has no name for is INTERNAL, and says which it was.
  const Status unknown = wire::FromGrpc({grpc::StatusCode::DATA_LOSS, "torn"});
  ExpectStatus(unknown, StatusCode::kInternal, "gRPC status 15: torn");
}

// A float's little-endian bytes, built from its bits (not by copying memory).
std::string LittleEndian(float value) {
  const auto bits = std::bit_cast<uint32_t>(value);
  std::string bytes;
  for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<char>((bits >> (8 * i)) & 0xff));
  return bytes;
}

TEST(ConversionsTest, FloatsAreTheirLittleEndianBytesAndComeBackBitForBit) {
  const std::vector<float> values = {0.0f,
                                     -0.0f,
                                     1.0f,
                                     -2.5f,
                                     std::numeric_limits<float>::denorm_min(),
                                     std::numeric_limits<float>::max(),
                                     std::numeric_limits<float>::infinity(),
                                     std::bit_cast<float>(uint32_t{0x7fc01234})};  // a NaN
  std::string expected;
  for (float v : values) expected += LittleEndian(v);
  const std::string bytes = wire::EncodeFloats(values);
  EXPECT_EQ(bytes, expected);

  std::vector<float> back = {9.0f, 9.0f, 9.0f, 9.0f, 9.0f, 9.0f, 9.0f, 9.0f, 9.0f, 9.0f};
  ASSERT_TRUE(wire::DecodeFloats(bytes, "palette", &back).ok());
  ASSERT_EQ(back.size(), values.size()) << "the output is not sized to the bytes";
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(std::bit_cast<uint32_t>(back[i]), std::bit_cast<uint32_t>(values[i])) << i;
  }
  // Nothing in, nothing out; and the string form reuses what it is given.
  std::string reused = "stale bytes of a longer palette";
  wire::EncodeFloats(std::span<const float>(values).first(1), &reused);
  EXPECT_EQ(reused, LittleEndian(values[0]));
  wire::EncodeFloats({}, &reused);
  EXPECT_TRUE(reused.empty());
  ASSERT_TRUE(wire::DecodeFloats("", "palette", &back).ok());
  EXPECT_TRUE(back.empty());
}

TEST(ConversionsTest, BytesThatAreNoWholeNumberOfFloatsAreRefusedNamingTheField) {
  std::vector<float> out = {1.0f};
  ExpectStatus(wire::DecodeFloats(std::string(7, '\0'), "palette", &out),
               StatusCode::kInvalidArgument, "palette holds 7 bytes, not a whole number");
  ExpectStatus(wire::DecodeFloats("x", "instance_palettes[3]", &out), StatusCode::kInvalidArgument,
               "instance_palettes[3] holds 1 bytes");
}

// Every value a descriptor lists converts and comes back; distinct wire values stay
// distinct model values.
template <typename WireEnum, typename ModelEnum>
void ExpectEveryWireValueRoundTrips(const google::protobuf::EnumDescriptor* descriptor,
                                    std::set<ModelEnum>* seen) {
  for (int i = 0; i < descriptor->value_count(); ++i) {
    const auto value = static_cast<WireEnum>(descriptor->value(i)->number());
    Result<ModelEnum> model = wire::FromWire(value);
    ASSERT_TRUE(model.ok()) << descriptor->value(i)->name() << ": " << model.status().ToString();
    EXPECT_EQ(wire::ToWire(*model), value) << descriptor->value(i)->name();
    EXPECT_TRUE(seen->insert(*model).second) << descriptor->value(i)->name() << " is a twin";
  }
}

TEST(ConversionsTest, EveryMethodRestEncodingAndEncodingRoundTripsBothWays) {
  std::set<SkinningMethod> methods;
  ExpectEveryWireValueRoundTrips<v1::SkinningMethod>(v1::SkinningMethod_descriptor(), &methods);
  EXPECT_EQ(methods,
            (std::set<SkinningMethod>{SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}));

  std::set<RestEncoding> rests;
  ExpectEveryWireValueRoundTrips<v1::RestEncoding>(v1::RestEncoding_descriptor(), &rests);
  EXPECT_EQ(rests, (std::set<RestEncoding>{RestEncoding::kFloat32, RestEncoding::kQuantized16,
                                           RestEncoding::kQuantized8Weights}));

  std::set<VertexEncoding> encodings;
  ExpectEveryWireValueRoundTrips<v1::Encoding>(v1::Encoding_descriptor(), &encodings);
  std::set<VertexEncoding> described;
  for (const EncodingDescription& e : Encodings()) {
    described.insert(e.id);
    // The wire's name for it is the encoding's own, upper-cased.
    std::string name = "ENCODING_";
    for (const char* c = e.name; *c != '\0'; ++c) name += static_cast<char>(std::toupper(*c));
    const auto* value = v1::Encoding_descriptor()->FindValueByName(name);
    ASSERT_NE(value, nullptr) << name;
    EXPECT_EQ(wire::ToWire(e.id), value->number()) << name;
  }
  EXPECT_EQ(encodings, described) << "the wire and the encoding table disagree";
}

TEST(ConversionsTest, EnumValuesThisSideDoesNotKnowAreRefusedNamingTheFieldAndTheKnownOnes) {
  ExpectStatus(wire::FromWire(static_cast<v1::SkinningMethod>(7)).status(),
               StatusCode::kInvalidArgument,
               "method = 7 is unknown; known: 0 (linear), 1 (dual-quaternion)");
  ExpectStatus(wire::FromWire(static_cast<v1::RestEncoding>(-1)).status(),
               StatusCode::kInvalidArgument, "header.rest_encoding = -1 is unknown; known: 0");
  ExpectStatus(wire::FromWire(static_cast<v1::Encoding>(3)).status(), StatusCode::kInvalidArgument,
               "encoding = 3 is unknown; known: float32 (0), float16 (1), snorm16 (2)");
  ExpectStatus(wire::FromWire(static_cast<v1::Encoding>(-2)).status(), StatusCode::kInvalidArgument,
               "encoding = -2 is unknown");
}

TEST(ConversionsTest, BoundsRoundTripEveryCoordinateInItsField) {
  const Bounds bounds{{-1.5f, 2.25f, -0.0f}, {3.0f, 1e30f, 7.125f}};
  v1::Bounds wire;
  wire::ToWire(bounds, &wire);
  EXPECT_EQ(wire.min_x(), -1.5f);
  EXPECT_EQ(wire.min_y(), 2.25f);
  EXPECT_EQ(wire.max_y(), 1e30f);
  EXPECT_EQ(wire.max_z(), 7.125f);
  v1::Bounds parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
  EXPECT_EQ(wire::FromWire(parsed), bounds);
}

// Through the message's bytes: what one side writes the other reads.
v1::SkinRequest Reparsed(const v1::SkinRequest& request) {
  v1::SkinRequest parsed;
  EXPECT_TRUE(parsed.ParseFromString(request.SerializeAsString()));
  return parsed;
}

bool SameWeights(std::span<const MorphWeight> a, std::span<const MorphWeight> b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](MorphWeight x, MorphWeight y) {
    return x.target == y.target && x.weight == y.weight;
  });
}

TEST(ConversionsTest, MorphWeightsRoundTripAndReplaceWhatWasThere) {
  const std::vector<MorphWeight> weights = {{3, 0.5f}, {0, 0.0f}, {1023, -1.0f}};
  v1::SkinRequest request;
  request.add_morph_targets(99);  // replaced, not appended to
  request.add_morph_weights(9.0f);
  wire::MorphWeightsToWire(weights, &request);
  std::vector<MorphWeight> back(10, MorphWeight{7, 7.0f});
  ASSERT_TRUE(wire::MorphWeightsFromWire(Reparsed(request), &back).ok());
  EXPECT_TRUE(SameWeights(back, weights)) << "zeros are sent as given and nothing stale stays";
  wire::MorphWeightsToWire({}, &request);
  ASSERT_TRUE(wire::MorphWeightsFromWire(Reparsed(request), &back).ok());
  EXPECT_TRUE(back.empty());
}

// The wire's one rule for morph weights: targets and weights pair up. Their counts and
// values against the mesh and the crowd are the engine's (CheckMorph: one place per check,
// docs/serving/frame-profile.md#checks), tested in tests/engine.
TEST(ConversionsTest, MorphWeightsThatDoNotPairUpAreRefusedNamingTheFields) {
  std::vector<MorphWeight> out(2, MorphWeight{7, 7.0f});  // what a refusal must leave alone
  v1::SkinRequest request;
  request.add_morph_targets(1);
  request.add_morph_targets(2);
  request.add_morph_weights(0.5f);
  ExpectStatus(wire::MorphWeightsFromWire(request, &out), StatusCode::kInvalidArgument,
               "morph_targets holds 2 entries but morph_weights 1");
  EXPECT_EQ(out.size(), 2u) << "copied before the check";
  EXPECT_EQ(out[0].target, 7u) << "copied before the check";
}

TEST(ConversionsTest, InstanceMorphWeightsRoundTripOneViewPerInstance) {
  const std::vector<std::vector<MorphWeight>> instances = {
      {{0, 1.0f}, {5, 0.25f}}, {}, {{2, -0.5f}}};
  v1::SkinRequest request;
  request.set_instances(3);
  wire::InstanceMorphWeightsToWire(instances, &request);
  std::vector<MorphWeight> flat;
  std::vector<std::span<const MorphWeight>> views;
  ASSERT_TRUE(wire::InstanceMorphWeightsFromWire(Reparsed(request), &flat, &views).ok());
  ASSERT_EQ(views.size(), instances.size());
  for (std::size_t k = 0; k < instances.size(); ++k) {
    EXPECT_TRUE(SameWeights(views[k], instances[k])) << "instance " << k;
  }
  EXPECT_EQ(flat.size(), 3u);
  // Set again: the field holds the new entries only. Unset: no views.
  wire::InstanceMorphWeightsToWire(std::span(instances).first(2), &request);
  EXPECT_EQ(request.instance_morph_weights_size(), 2);
  request.clear_instance_morph_weights();
  ASSERT_TRUE(wire::InstanceMorphWeightsFromWire(request, &flat, &views).ok());
  EXPECT_TRUE(views.empty());
}

TEST(ConversionsTest, MalformedInstanceMorphWeightsAreRefusedNamingTheFieldAndTheInstance) {
  std::vector<MorphWeight> flat;
  std::vector<std::span<const MorphWeight>> views;
  const std::vector<std::vector<MorphWeight>> two = {{{0, 1.0f}}, {{1, 1.0f}}};
  v1::SkinRequest request;
  request.set_instances(2);
  wire::InstanceMorphWeightsToWire(two, &request);
  request.mutable_instance_morph_weights(1)->add_targets(4);
  ExpectStatus(wire::InstanceMorphWeightsFromWire(request, &flat, &views),
               StatusCode::kInvalidArgument,
               "instance_morph_weights[1]: targets holds 2 entries but weights 1");
  EXPECT_TRUE(views.empty()) << "a refused field left views behind";
}

}  // namespace
}  // namespace skinserve::testing
