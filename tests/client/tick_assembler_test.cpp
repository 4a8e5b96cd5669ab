// TickAssembler against tick answers built here by hand: characters' parts in finish order
// reassembled per character; a refused tick, a failed character and every answer against
// the contract (a part of a character the tick does not have, a final part with the wrong
// number of headers, a character whose vertices never came) fail with a status naming the
// tick and the character, never silently.
#include <grpcpp/impl/codegen/proto_utils.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "skinserve/client/tick.h"

namespace skinserve::client {
namespace {

constexpr uint64_t kFrame = 12;

grpc::ByteBuffer Serialized(const v1::SkinResponse& part) {
  grpc::ByteBuffer bytes;
  bool own = false;
  EXPECT_TRUE(grpc::SerializationTraits<v1::SkinResponse>::Serialize(part, &bytes, &own).ok());
  return bytes;
}

// Character `c`'s vertices [first, first + count) of `total`, float32, `last` false.
v1::SkinResponse VertexPart(uint32_t c, uint32_t first, uint32_t count, uint32_t total,
                            float value) {
  v1::SkinResponse part;
  part.set_frame(kFrame);
  part.set_character(c);
  part.set_first_vertex(first);
  part.set_vertex_count(count);
  part.set_total_vertices(total);
  part.set_instances(1);
  const std::vector<float> positions(3ull * count, value + static_cast<float>(first));
  part.set_positions(positions.data(), positions.size() * sizeof(float));
  return part;
}

v1::SkinResponse Header(uint32_t c, uint32_t total) {
  v1::SkinResponse header;
  header.set_frame(kFrame);
  header.set_character(c);
  header.set_total_vertices(total);
  header.set_instances(1);
  header.set_last(true);
  header.mutable_timing()->set_compute_ns(1000 + c);
  return header;
}

v1::SkinResponse Final(std::vector<v1::SkinResponse> headers) {
  v1::SkinResponse part;
  part.set_frame(kFrame);
  part.set_last(true);
  for (auto& h : headers) *part.mutable_tick()->add_characters() = std::move(h);
  return part;
}

class TickAssemblerTest : public ::testing::Test {
 protected:
  TickAssemblerTest() {
    tick_.set_frame(kFrame);
    tick_.Add("mesh-a", palette_);
    tick_.Add("mesh-b", palette_);
  }
  // Feeds `parts` in order; whether the last one completed the tick.
  bool Feed(const std::vector<v1::SkinResponse>& parts) {
    TickAssembler assembler(tick_, &result_);
    bool complete = false;
    for (const auto& p : parts) {
      EXPECT_FALSE(complete) << "a part after the tick was complete";
      complete = assembler.Add(Serialized(p), &reader_);
    }
    return complete;
  }

  std::vector<float> palette_ = std::vector<float>(12, 0.0f);
  Tick tick_;
  TickResult result_;
  RawPart reader_;
};

TEST_F(TickAssemblerTest, CharactersInFinishOrderAreReassembledEachInItsResult) {
  // Character 1 finished first; character 0 came in two parts.
  ASSERT_TRUE(Feed({VertexPart(1, 0, 3, 3, 7.0f), VertexPart(0, 0, 2, 4, 1.0f),
                    VertexPart(0, 2, 2, 4, 1.0f), Final({Header(0, 4), Header(1, 3)})}));
  ASSERT_TRUE(result_.status.ok()) << result_.status.ToString();
  EXPECT_EQ(result_.frame, kFrame);
  ASSERT_EQ(result_.characters.size(), 2u);
  EXPECT_EQ(result_.failed(), 0u);
  const FrameResult& a = result_.characters[0];
  const FrameResult& b = result_.characters[1];
  ASSERT_TRUE(a.status.ok()) << a.status.ToString();
  ASSERT_EQ(a.positions.size(), 12u);
  EXPECT_EQ(a.positions[0], 1.0f);
  EXPECT_EQ(a.positions[11], 3.0f);  // the second part's vertices (first = 2)
  EXPECT_EQ(a.timing.compute_ns(), 1000);
  ASSERT_EQ(b.positions.size(), 9u);
  EXPECT_EQ(b.positions[8], 7.0f);
  EXPECT_EQ(b.timing.compute_ns(), 1001);
}

TEST_F(TickAssemblerTest, AFailedCharacterTakesItsHeadersErrorAndTheOtherIsAnswered) {
  v1::SkinResponse failed = Header(0, 0);
  failed.mutable_error()->set_code(grpc::StatusCode::NOT_FOUND);
  failed.mutable_error()->set_message("character 0: mesh mesh-a is not stored");
  ASSERT_TRUE(Feed({VertexPart(1, 0, 3, 3, 7.0f), Final({failed, Header(1, 3)})}));
  ASSERT_TRUE(result_.status.ok());
  EXPECT_EQ(result_.characters[0].status.code(), StatusCode::kNotFound);
  EXPECT_NE(result_.characters[0].status.message().find("character 0"), std::string::npos);
  EXPECT_TRUE(result_.characters[0].positions.empty());
  EXPECT_TRUE(result_.characters[1].status.ok());
  EXPECT_EQ(result_.failed(), 1u);
}

TEST_F(TickAssemblerTest, ATickRefusedWholeFailsEveryCharacterWithTheServersStatus) {
  v1::SkinResponse refused;
  refused.set_frame(kFrame);
  refused.set_last(true);
  refused.mutable_error()->set_code(grpc::StatusCode::RESOURCE_EXHAUSTED);
  refused.mutable_error()->set_message("at most 256 (--max-tick-characters)");
  ASSERT_TRUE(Feed({refused}));
  EXPECT_EQ(result_.status.code(), StatusCode::kResourceExhausted);
  for (const FrameResult& r : result_.characters) {
    EXPECT_EQ(r.status.code(), StatusCode::kResourceExhausted);
  }
}

TEST_F(TickAssemblerTest, AnswersAgainstTheContractFailNamingTickAndCharacter) {
  // A part of a character the tick does not have.
  EXPECT_FALSE(Feed({VertexPart(5, 0, 3, 3, 1.0f)}));
  EXPECT_EQ(result_.status.code(), StatusCode::kInternal);
  EXPECT_NE(result_.status.message().find("tick 12: a part of character 5"), std::string::npos)
      << result_.status.ToString();
  // A final part with one header for two characters.
  ASSERT_TRUE(Feed({VertexPart(0, 0, 3, 3, 1.0f), Final({Header(0, 3)})}));
  EXPECT_EQ(result_.status.code(), StatusCode::kInternal);
  EXPECT_NE(result_.status.message().find("1 character headers for 2"), std::string::npos)
      << result_.status.ToString();
  // Character 1's vertices never came (its header says it was answered over the wire).
  ASSERT_TRUE(Feed({VertexPart(0, 0, 3, 3, 1.0f), Final({Header(0, 3), Header(1, 3)})}));
  EXPECT_TRUE(result_.status.ok());
  EXPECT_TRUE(result_.characters[0].status.ok());
  EXPECT_EQ(result_.characters[1].status.code(), StatusCode::kInternal);
  EXPECT_NE(result_.characters[1].status.message().find("character 1 was not answered in full"),
            std::string::npos)
      << result_.characters[1].status.ToString();
  // A part of another frame.
  v1::SkinResponse other = VertexPart(0, 0, 3, 3, 1.0f);
  other.set_frame(kFrame + 1);
  EXPECT_FALSE(Feed({other}));
  EXPECT_EQ(result_.status.code(), StatusCode::kInternal);
}

}  // namespace
}  // namespace skinserve::client
