// SkinRequestReader against hand-built requests: every repeated field is counted, packed or
// not, against its limit before the parse; the parsed size is bounded by what the scan
// charges (protobuf's own SpaceUsedLong is the independent measure); a refused request
// names its field, its count and its limit; a large request's storage and charge go.
#include "frames/skin_request_reader.h"

#include <grpcpp/impl/codegen/proto_utils.h>
#include <gtest/gtest.h>

#include <string>
#include <tuple>

namespace skinserve::server {
namespace {

grpc::ByteBuffer Bytes(const v1::SkinRequest& request) {
  grpc::ByteBuffer bytes;
  bool own = false;
  EXPECT_TRUE(grpc::SerializationTraits<v1::SkinRequest>::Serialize(request, &bytes, &own).ok());
  return bytes;
}

grpc::ByteBuffer Bytes(const std::string& raw) {
  grpc::Slice slice(raw);
  return grpc::ByteBuffer(&slice, 1);
}

v1::SkinRequest Crowd(uint32_t instances, uint32_t targets_each) {
  v1::SkinRequest request;
  request.set_mesh_id("m");
  request.set_frame(41);
  request.set_instances(instances);
  request.set_palette(std::string(77 * 48, '\1'));
  for (uint32_t i = 0; i < instances; ++i) {
    v1::MorphWeights* weights = request.add_instance_morph_weights();
    for (uint32_t t = 0; t < targets_each; ++t) {
      weights->add_targets(t * 300);  // 2-byte varints past 127
      weights->add_weights(0.25f);
    }
  }
  return request;
}

TEST(SkinRequestReaderTest, CountsWithinTheLimitsParseAndTheChargeBoundsTheParsedSize) {
  InflightBudget budget(64 << 20);
  const SkinRequestLimits limits{.max_instances = 64, .max_morph_weights = 1024};
  for (const auto& [instances, targets] :
       {std::pair{1u, 0u}, std::pair{64u, 1024u}, std::pair{3u, 1000u}}) {
    SkinRequestReader reader(&budget, limits);
    v1::SkinRequest request = Crowd(instances, targets);
    for (uint32_t t = 0; t < targets; ++t) {
      request.add_morph_targets(t);
      request.add_morph_weights(0.5f);
    }
    grpc::ByteBuffer bytes = Bytes(request);
    ASSERT_TRUE(reader.Read(&bytes).ok()) << instances << " x " << targets;
    EXPECT_EQ(reader.request().frame(), 41u);
    EXPECT_EQ(reader.request().instance_morph_weights_size(), static_cast<int>(instances));
    EXPECT_EQ(reader.scan().frame, 41u);
    EXPECT_GE(reader.scan().parsed_bytes, reader.request().SpaceUsedLong())
        << instances << " x " << targets << ": the charge is below what the parse holds";
    EXPECT_EQ(budget.used(), reader.charged());
    EXPECT_EQ(reader.charged(), reader.scan().parsed_bytes);
  }
  EXPECT_EQ(budget.used(), 0u) << "a reader keeps its charge past its life";
}

TEST(SkinRequestReaderTest, CountsOverTheLimitsAreRefusedBeforeTheParseNamingFieldAndLimit) {
  InflightBudget budget(1 << 30);
  const SkinRequestLimits limits{.max_instances = 64, .max_morph_weights = 1024};
  const auto expect_refused = [&](const v1::SkinRequest& request, const std::string& field,
                                  const std::string& count) {
    SkinRequestReader reader(&budget, limits);
    grpc::ByteBuffer bytes = Bytes(request);
    const Status status = reader.Read(&bytes);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << field;
    EXPECT_NE(status.message().find(field + " has " + count), std::string::npos)
        << status.message();
    EXPECT_FALSE(reader.scan().malformed);
    EXPECT_EQ(reader.scan().frame, 41u) << "the refusal must be able to name its frame";
    EXPECT_EQ(reader.request().instance_morph_weights_size(), 0) << "parsed although refused";
    EXPECT_EQ(budget.used(), 0u);
  };
  // The attack of issue 42: empty entries, 2 bytes each on the wire.
  v1::SkinRequest request = Crowd(0, 0);
  for (int i = 0; i < 100'000; ++i) request.add_instance_morph_weights();
  expect_refused(request, "instance_morph_weights", "more than 64 entries");
  expect_refused(Crowd(65, 0), "instance_morph_weights", "more than 64 entries");
  expect_refused(Crowd(2, 1025), "instance_morph_weights[0].targets", "1025 entries; at most 1024");
  request = Crowd(1, 0);
  for (int t = 0; t < 1025; ++t) request.add_morph_weights(0.5f);
  expect_refused(request, "morph_weights", "1025 entries; at most 1024");
  request = Crowd(1, 0);
  for (int t = 0; t < 1025; ++t) request.add_morph_targets(static_cast<uint32_t>(t));
  expect_refused(request, "morph_targets", "1025 entries; at most 1024");
}

TEST(SkinRequestReaderTest, UnpackedListsCountAsPackedOnes) {
  // Field 12 (morph_targets) written unpacked: one tag and varint per value, which a
  // parser must accept as the packed form.
  std::string raw = "\x18\x29";  // frame = 41
  for (int t = 0; t < 1025; ++t) raw += std::string("\x60") + static_cast<char>(t % 100);
  InflightBudget budget(1 << 30);
  SkinRequestReader reader(&budget, {});
  grpc::ByteBuffer bytes = Bytes(raw);
  const Status status = reader.Read(&bytes);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("morph_targets has 1025 entries"), std::string::npos)
      << status.message();
  raw.resize(2 + 2 * 1024);  // 1024 values: within the limit
  SkinRequestReader within(&budget, {});
  bytes = Bytes(raw);
  ASSERT_TRUE(within.Read(&bytes).ok());
  EXPECT_EQ(within.request().morph_targets_size(), 1024);
}

TEST(SkinRequestReaderTest, BytesThatAreNoSkinRequestAreMalformed) {
  InflightBudget budget(1 << 30);
  for (const std::string& raw : {std::string("\x72\x05\x0a", 3),      // an entry cut short
                                 std::string("\x62\x03\x80\x80", 4),  // a packed list cut short
                                 std::string("\xff\xff\xff\xff\xff\xff", 6)}) {
    SkinRequestReader reader(&budget, {});
    grpc::ByteBuffer bytes = Bytes(raw);
    const Status status = reader.Read(&bytes);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_TRUE(reader.scan().malformed) << status.message();
  }
  EXPECT_EQ(budget.used(), 0u);
}

TEST(SkinRequestReaderTest, TheParsedSizeIsChargedAndRefusedWhenTheBudgetCannotHoldIt) {
  const v1::SkinRequest request = Crowd(64, 1024);  // ~1 MB parsed
  InflightBudget small(256 << 10);
  SkinRequestReader reader(&small, {});
  grpc::ByteBuffer bytes = Bytes(request);
  const Status status = reader.Read(&bytes);
  EXPECT_EQ(status.code(), StatusCode::kResourceExhausted) << status.message();
  EXPECT_NE(status.message().find("--inflight-budget-mb"), std::string::npos) << status.message();
  EXPECT_EQ(small.used(), 0u);
  EXPECT_EQ(reader.request().instance_morph_weights_size(), 0) << "parsed although refused";
}

TEST(SkinRequestReaderTest, ALargeRequestsStorageAndChargeGoAfterItsFrameASmallOneStays) {
  InflightBudget budget(1 << 30);
  SkinRequestReader reader(&budget, {});
  grpc::ByteBuffer bytes = Bytes(Crowd(64, 1024));
  ASSERT_TRUE(reader.Read(&bytes).ok());
  ASSERT_GT(reader.charged(), kKeptRequestBytes);
  reader.Trim();
  EXPECT_EQ(budget.used(), 0u);
  EXPECT_LT(reader.request().SpaceUsedLong(), 4096u) << "the large request's storage stayed";
  bytes = Bytes(Crowd(1, 8));
  ASSERT_TRUE(reader.Read(&bytes).ok());
  const uint64_t small = reader.charged();
  ASSERT_GT(small, 0u);
  ASSERT_LE(small, kKeptRequestBytes);
  reader.Trim();
  EXPECT_EQ(budget.used(), small) << "a small request's storage is kept, and so is its charge";
  EXPECT_EQ(reader.request().instance_morph_weights_size(), 1);
}

// A tick of `characters` crowds, each as Crowd(instances, targets) without its frame.
v1::SkinRequest TickOf(uint32_t characters, uint32_t instances, uint32_t targets) {
  v1::SkinRequest tick;
  tick.set_frame(41);
  for (uint32_t c = 0; c < characters; ++c) {
    v1::SkinRequest* character = tick.add_characters();
    *character = Crowd(instances, targets);
    character->clear_frame();
  }
  return tick;
}

TEST(SkinRequestReaderTest, ATicksCharactersAreCountedAndTheirParsedSizeIsCharged) {
  InflightBudget budget(1 << 30);
  const SkinRequestLimits limits{.max_tick_characters = 64};
  for (const auto& [characters, instances, targets] :
       {std::tuple{1u, 1u, 0u}, std::tuple{64u, 1u, 0u}, std::tuple{8u, 16u, 200u}}) {
    SCOPED_TRACE(::testing::Message() << characters << " x " << instances << " x " << targets);
    SkinRequestReader reader(&budget, limits);
    grpc::ByteBuffer bytes = Bytes(TickOf(characters, instances, targets));
    ASSERT_TRUE(reader.Read(&bytes).ok());
    EXPECT_EQ(reader.scan().characters, characters);
    EXPECT_EQ(reader.scan().frame, 41u);
    EXPECT_EQ(reader.request().characters_size(), static_cast<int>(characters));
    EXPECT_GE(reader.scan().parsed_bytes, reader.request().SpaceUsedLong())
        << "the charge is below what the parse holds";
    EXPECT_EQ(budget.used(), reader.scan().parsed_bytes);
  }
}

TEST(SkinRequestReaderTest, ATickOverItsLimitsIsRefusedBeforeTheParseNamingFieldOrOption) {
  InflightBudget budget(1 << 30);
  const SkinRequestLimits limits{.max_tick_characters = 8, .max_tick_bytes = 64 << 10};
  const auto refused = [&](const v1::SkinRequest& request, StatusCode code,
                           const std::string& words) {
    SkinRequestReader reader(&budget, limits);
    grpc::ByteBuffer bytes = Bytes(request);
    const Status status = reader.Read(&bytes);
    EXPECT_EQ(status.code(), code) << status.ToString();
    EXPECT_NE(status.message().find(words), std::string::npos) << status.message();
    EXPECT_EQ(reader.scan().frame, 41u) << "the refusal must be able to name its frame";
    EXPECT_EQ(reader.request().characters_size(), 0) << "parsed although refused";
    EXPECT_EQ(budget.used(), 0u);
  };
  refused(TickOf(9, 1, 0), StatusCode::kResourceExhausted, "at most 8 (--max-tick-characters)");
  // Nested characters count too.
  v1::SkinRequest nested = TickOf(2, 1, 0);
  for (int i = 0; i < 7; ++i) nested.mutable_characters(1)->add_characters();
  refused(nested, StatusCode::kResourceExhausted, "--max-tick-characters");
  v1::SkinRequest large = TickOf(2, 1, 0);
  for (int c = 0; c < 2; ++c) large.mutable_characters(c)->set_palette(std::string(40 << 10, '\1'));
  refused(large, StatusCode::kResourceExhausted, "; at most 65536 (--max-tick-bytes)");
  refused(TickOf(2, 2, 1025), StatusCode::kInvalidArgument,
          "characters[0].instance_morph_weights[0].targets has 1025 entries");
  v1::SkinRequest lists = TickOf(3, 1, 0);
  for (int t = 0; t < 1025; ++t) lists.mutable_characters(2)->add_morph_weights(0.5f);
  refused(lists, StatusCode::kInvalidArgument, "characters[2].morph_weights has 1025 entries");
  v1::SkinRequest deep = TickOf(1, 1, 0);
  deep.mutable_characters(0)->add_characters()->add_characters();
  refused(deep, StatusCode::kInvalidArgument,
          "characters[0].characters[0].characters is set: ticks do not nest");
  // A plain frame stays within gRPC's default 4 MiB, which the server raises for ticks.
  v1::SkinRequest frame = Crowd(1, 0);
  frame.set_palette(std::string(kMaxFrameRequestBytes, '\1'));
  refused(frame, StatusCode::kResourceExhausted, "at most 4194304 for one frame");
}

}  // namespace
}  // namespace skinserve::server
