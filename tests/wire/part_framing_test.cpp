// A part framed by WritePartFraming, with its vertex bytes beside it as the server sends
// them, must be a SkinResponse to protobuf's own parser (the independent reference) and to
// the clients' RawPart, field for field and byte for byte, at every varint length boundary
// of the payload, with normals and with tangents (field 17: a two-byte tag).
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "skinserve/wire/part_framing.h"
#include "skinserve/wire/raw_part.h"

namespace skinserve::wire {
namespace {

v1::SkinResponse Header() {
  v1::SkinResponse header;
  header.set_frame(123456789);
  header.set_first_vertex(4096);
  header.set_vertex_count(77);
  header.set_total_vertices(100003);
  header.set_last(true);
  header.set_instance(3);
  header.set_instances(8);
  header.set_encoding(v1::ENCODING_SNORM16);
  header.mutable_timing()->set_queued_ns(1234);
  header.mutable_bounds()->set_min_x(-1.5f);
  header.mutable_bounds()->set_max_z(2.5f);
  return header;
}

std::string Bytes(std::size_t n, uint32_t seed) {
  std::mt19937 random(seed);
  std::string bytes(n, '\0');
  for (char& c : bytes) c = static_cast<char>(random());
  return bytes;
}

TEST(PartFramingTest, FramedPartsParseAsTheMessageTheyStandFor) {
  for (int fields = 1; fields <= 3; ++fields) {
    const bool normals = fields >= 2, tangents = fields == 3;
    for (std::size_t payload : {0u, 1u, 127u, 128u, 16383u, 16384u, 2097151u, 2097152u}) {
      SCOPED_TRACE(testing::Message() << "payload " << payload << ", normals " << normals
                                      << ", tangents " << tangents);
      const v1::SkinResponse header = Header();
      std::vector<std::byte> room(256);
      const std::size_t tangent_payload = tangents ? payload / 3 * 4 + 1 : 0;
      auto framing =
          WritePartFraming(header, header.ByteSizeLong(), payload, normals, room, tangent_payload);
      ASSERT_TRUE(framing.ok()) << framing.status().ToString();
      EXPECT_EQ(framing->normals_tag_bytes == 0, !normals);
      EXPECT_EQ(framing->tangents_tag_bytes == 0, !tangents);

      const std::string positions = Bytes(payload, 1);
      const std::string normal_bytes = Bytes(payload, 2);
      std::string wire(reinterpret_cast<const char*>(room.data()), framing->header_bytes);
      wire += positions;
      if (normals) {
        wire.append(reinterpret_cast<const char*>(room.data()) + framing->header_bytes,
                    framing->normals_tag_bytes);
        wire += normal_bytes;
      }
      const std::string tangent_bytes = Bytes(tangent_payload, 3);
      if (tangents) {
        wire.append(reinterpret_cast<const char*>(room.data()) + framing->header_bytes +
                        framing->normals_tag_bytes,
                    framing->tangents_tag_bytes);
        wire += tangent_bytes;
      }

      v1::SkinResponse parsed;
      ASSERT_TRUE(parsed.ParseFromString(wire));
      v1::SkinResponse expected = header;
      expected.set_positions(positions);
      if (normals) expected.set_normals(normal_bytes);
      if (tangents) expected.set_tangents(tangent_bytes);
      EXPECT_EQ(parsed.SerializeAsString(), expected.SerializeAsString());

      // The clients' reader: the same header, the same field sizes.
      grpc::Slice slice(wire.data(), wire.size());
      RawPart raw;
      ASSERT_TRUE(raw.Parse(grpc::ByteBuffer(&slice, 1)));
      EXPECT_EQ(raw.header().frame(), header.frame());
      EXPECT_EQ(raw.header().instance(), header.instance());
      EXPECT_EQ(raw.header().bounds().max_z(), header.bounds().max_z());
      EXPECT_EQ(raw.positions_size(), payload);
      EXPECT_EQ(raw.normals_size(), normals ? payload : 0);
      EXPECT_EQ(raw.tangents_size(), tangent_payload);
    }
  }
}

TEST(PartFramingTest, AHeaderThatDoesNotFitIsAnErrorNamingTheSizes) {
  v1::SkinResponse header = Header();
  for (int i = 0; i < 20; ++i) header.add_instance_bounds()->set_min_x(1.0f);
  const std::size_t size = header.ByteSizeLong();
  std::vector<std::byte> room(size + 2 * kMaxFieldTagBytes - 1);  // short of two tags' room
  auto framing = WritePartFraming(header, size, 1000, /*normals=*/true, room);
  ASSERT_FALSE(framing.ok());
  EXPECT_NE(framing.status().message().find(std::to_string(size) + " bytes"), std::string::npos)
      << framing.status().message();
  // Without normals one tag's room is enough.
  EXPECT_TRUE(WritePartFraming(header, size, 1000, /*normals=*/false, room).ok());
}

// Unknown groups (no SkinResponse field is one, but the wire allows them): RawPart copies
// them into the header field by field and must accept and refuse exactly what protobuf's
// parser does, at every depth. Found by raw_part_fuzzer: an overlong (6-byte) tag inside a
// group, which protobuf refuses, was rewritten canonically and accepted.
TEST(PartFramingTest, UnknownGroupsAreTakenAndRefusedAsProtobufDoes) {
  const std::string header = Header().SerializeAsString();
  const std::string group_start = "\xa3\x01", group_end = "\xa4\x01";  // field 20
  const std::string positions = std::string("\x32\x0c") + Bytes(12, 7);
  const struct {
    const char* what;
    std::string inner;
    bool taken;  // by protobuf: checked, so that the cases cover both answers
  } cases[] = {
      {"varint, fixed32, bytes and a nested group",
       std::string("\x08\x96\x01\x15\x01\x02\x03\x04\x1a\x02hi\x23\x08\x01\x24"), true},
      {"an empty group", "", true},
      {"an overlong tag (6 bytes)", std::string("\xa1\xa1\xa1\xa1\xa1\x50") + "12345678", false},
      {"an overlong length (6 bytes)", std::string("\x1a\x82\x80\x80\x80\x80\x00hi"), false},
      {"an end of another group", "\x24", false},
      {"a tag 0", std::string("\x00", 1), false},
      {"no end", "\x08\x01", false},
  };
  for (const auto& c : cases) {
    const bool ends = std::string(c.what) != "no end";
    const std::string message =
        header + group_start + c.inner + (ends ? group_end : "") + positions;
    v1::SkinResponse parsed;
    const bool protobuf_ok = parsed.ParseFromString(message);
    ASSERT_EQ(protobuf_ok, c.taken) << c.what;
    const grpc::Slice slice(message.data(), message.size());
    const grpc::ByteBuffer bytes(&slice, 1);
    RawPart raw;
    ASSERT_EQ(raw.Parse(bytes), protobuf_ok) << c.what;
    if (!protobuf_ok) continue;
    EXPECT_EQ(raw.positions_size(), parsed.positions().size()) << c.what;
    parsed.clear_positions();
    EXPECT_EQ(raw.header().SerializeAsString(), parsed.SerializeAsString()) << c.what;
  }
}

}  // namespace
}  // namespace skinserve::wire
