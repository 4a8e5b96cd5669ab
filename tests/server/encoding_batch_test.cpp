// Encodings and crowd batches through a real server: every encoding and batch size on
// every backend, decoded with the shared codec and compared with the float64 reference
// within the bound of the encoding used (the proto's formula); batches mixing good and
// bad instances; one stream switching encodings between frames; the in-flight budget and
// the reuse of a stream's frame jobs.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <thread>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/v1/skinning.grpc.pb.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using Stream = grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>;

// One answered frame, decoded to float32 per instance.
struct Answer {
  grpc::StatusCode error = grpc::StatusCode::OK;
  std::string message;
  std::vector<std::vector<float>> positions, normals;
  std::vector<Bounds> bounds;
  std::vector<uint32_t> parts;  // per instance (a packed part counts for each of its own)
  uint32_t messages = 0;        // parts of the frame
};

v1::SkinRequest MakeRequest(const std::string& mesh_id, const std::string& backend, uint64_t frame,
                            uint32_t instances, v1::Encoding encoding, bool normals,
                            const std::vector<float>& palettes, bool pack = false) {
  v1::SkinRequest request;
  request.set_pack_instances(pack);
  request.set_mesh_id(mesh_id);
  request.set_backend(backend);
  request.set_frame(frame);
  request.set_instances(instances);
  request.set_encoding(encoding);
  request.set_want_normals(normals);
  request.set_palette(palettes.data(), palettes.size() * sizeof(float));
  return request;
}

// K palettes, one pose per instance (so an instance answered with another's vertices fails).
std::vector<float> CrowdPalettes(uint32_t joints, uint32_t instances, uint64_t frame) {
  std::vector<float> palettes;
  for (uint32_t i = 0; i < std::max(instances, 1u); ++i) {
    const auto one = MakeSyntheticPalette(joints, 7 + i, frame + i);
    palettes.insert(palettes.end(), one.begin(), one.end());
  }
  return palettes;
}

// Reads one frame's parts (or its error) and decodes them; checks every part's header.
template <typename Reader>
Answer ReadFrame(Reader& stream, uint64_t frame, uint32_t vertex_count, uint32_t instances,
                 v1::Encoding encoding, bool normals) {
  Answer answer;
  const uint32_t k = std::max(instances, 1u);
  answer.positions.assign(k, std::vector<float>(3ull * vertex_count, NAN));
  answer.normals.assign(k, std::vector<float>(normals ? 3ull * vertex_count : 0, NAN));
  answer.bounds.resize(k);
  answer.parts.assign(k, 0);
  const auto enc = static_cast<VertexEncoding>(encoding);
  v1::SkinResponse part;
  uint32_t expected_instance = 0, expected_first = 0;
  while (true) {
    if (!stream.Read(&part)) {
      ADD_FAILURE() << "stream ended before frame " << frame << "'s last part";
      answer.error = grpc::StatusCode::UNKNOWN;
      return answer;
    }
    EXPECT_EQ(part.frame(), frame);
    if (part.has_error()) {
      EXPECT_TRUE(part.last());
      answer.error = static_cast<grpc::StatusCode>(part.error().code());
      answer.message = part.error().message();
      return answer;
    }
    EXPECT_EQ(part.instances(), k);
    EXPECT_EQ(part.encoding(), encoding);
    EXPECT_EQ(part.total_vertices(), vertex_count);
    // Parts come instance by instance, each in vertex order.
    EXPECT_EQ(part.instance(), expected_instance);
    EXPECT_EQ(part.first_vertex(), expected_first);
    EXPECT_LE(part.positions().size() + part.normals().size(), 1u << 20);
    ++answer.messages;
    // Packed: several whole instances back to back, each with its own box.
    const uint32_t packed = std::max(part.instance_count(), 1u);
    if (packed > 1) {
      EXPECT_EQ(part.first_vertex(), 0u);
      EXPECT_EQ(part.vertex_count(), vertex_count);
      if (encoding == v1::ENCODING_SNORM16) {
        EXPECT_EQ(part.instance_bounds_size(), static_cast<int>(packed));
      }
    }
    const std::size_t first = 3ull * part.first_vertex(), count = 3ull * part.vertex_count();
    const std::size_t instance_bytes = count * EncodedBytesPerValue(enc);
    EXPECT_EQ(part.positions().size(), packed * instance_bytes);
    for (uint32_t j = 0; j < packed && part.positions().size() == packed * instance_bytes; ++j) {
      const uint32_t i = std::min(part.instance() + j, k - 1);
      const v1::Bounds& b = packed > 1 && encoding == v1::ENCODING_SNORM16
                                ? part.instance_bounds(static_cast<int>(j))
                                : part.bounds();
      const Bounds box{{b.min_x(), b.min_y(), b.min_z()}, {b.max_x(), b.max_y(), b.max_z()}};
      answer.bounds[i] = box;
      ++answer.parts[i];
      const auto bytes = [&](const std::string& s) {
        return std::span<const std::byte>(reinterpret_cast<const std::byte*>(s.data()), s.size())
            .subspan(j * instance_bytes, instance_bytes);
      };
      Status s = DecodePositions(enc, bytes(part.positions()), box,
                                 std::span<float>(answer.positions[i]).subspan(first, count));
      EXPECT_TRUE(s.ok()) << s.ToString();
      if (normals) {
        s = DecodeNormals(enc, bytes(part.normals()),
                          std::span<float>(answer.normals[i]).subspan(first, count));
        EXPECT_TRUE(s.ok()) << s.ToString();
      }
    }
    if (packed > 1) {
      expected_instance += packed;
      if (part.last()) {
        EXPECT_EQ(expected_instance, k) << "the last part ends the last instance";
        return answer;
      }
      continue;
    }
    expected_first += part.vertex_count();
    if (expected_first >= vertex_count) {
      ++expected_instance;
      expected_first = 0;
    }
    if (part.last()) {
      EXPECT_EQ(expected_instance, k) << "the last part ends the last instance";
      return answer;
    }
  }
}

// Every decoded value within float32's tolerance plus the encoding's stated bound.
void ExpectWithinBound(const Mesh& mesh, std::span<const float> palette,
                       std::span<const float> positions, std::span<const float> normals,
                       v1::Encoding encoding, const Bounds& box) {
  const auto enc = static_cast<VertexEncoding>(encoding);
  const ReferenceFrame reference = ReferenceSkin(mesh, palette);
  const Deviation float32 = CompareWithReference(mesh, palette, positions, normals);
  std::size_t outside = 0;
  double worst = 0;
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const double x = reference.positions[v];
    const double error = std::abs(positions[v] - x);  // NaN: not <= bound
    const double bound =
        float32.position_tolerance + PositionEncodingError(enc, box, static_cast<int>(v % 3), x);
    if (!(error <= bound)) ++outside;
    worst = std::max(worst, error / bound);
  }
  for (std::size_t v = 0; v < normals.size(); ++v) {
    const double n = reference.normals[v];
    const double error = std::abs(normals[v] - n);
    if (!(error <= float32.normal_tolerance + NormalEncodingError(enc, n))) ++outside;
  }
  EXPECT_EQ(outside, 0u) << "values outside the bound; worst error / bound " << worst;
  if (encoding == v1::ENCODING_SNORM16) {  // the box is the instance's, as skinned
    for (int axis = 0; axis < 3; ++axis) {
      double lo = INFINITY, hi = -INFINITY;
      for (std::size_t v = axis; v < reference.positions.size(); v += 3) {
        lo = std::min(lo, reference.positions[v]);
        hi = std::max(hi, reference.positions[v]);
      }
      EXPECT_NEAR(box.min[axis], lo, float32.position_tolerance);
      EXPECT_NEAR(box.max[axis], hi, float32.position_tolerance);
    }
  }
}

constexpr v1::Encoding kEncodings[] = {v1::ENCODING_FLOAT32, v1::ENCODING_FLOAT16,
                                       v1::ENCODING_SNORM16};

TEST(EncodingBatchTest, EveryEncodingAndBatchSizeOnEveryBackendOnOneStream) {
  TestServer t;
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 2000, .influences = 3, .normals = true, .seed = 4});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  const auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int backends = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    ++backends;
    SCOPED_TRACE(backend.id());
    grpc::ClientContext context;
    auto stream = stub->StreamSkin(&context);
    uint64_t frame = 0;
    // The encoding, the batch size and the packing change from frame to frame on the same
    // stream.
    for (uint32_t instances : {0u, 1u, 3u}) {
      for (v1::Encoding encoding : kEncodings) {
        for (bool normals : {false, true}) {
          const bool pack = frame % 2 == 1;
          SCOPED_TRACE(::testing::Message() << "K=" << instances << " encoding=" << encoding
                                            << " normals=" << normals << " pack=" << pack);
          const auto palettes = CrowdPalettes(77, instances, frame);
          ASSERT_TRUE(stream->Write(MakeRequest(info->mesh_id(), backend.id(), frame, instances,
                                                encoding, normals, palettes, pack)));
          const Answer answer = ReadFrame(*stream, frame, 2000, instances, encoding, normals);
          ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
          // 2000 vertices: one part per instance, or every instance in one packed part.
          EXPECT_EQ(answer.messages, pack ? 1u : std::max(instances, 1u));
          for (uint32_t i = 0; i < std::max(instances, 1u); ++i) {
            SCOPED_TRACE(::testing::Message() << "instance " << i);
            ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                              answer.positions[i], answer.normals[i], encoding, answer.bounds[i]);
          }
          ++frame;
        }
      }
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  EXPECT_GE(backends, 4);
}

// 50k vertices with normals are skinned into the compute thread's scratch and encoded from
// there; 200k are over the scratch's limit and go through the frame's own float buffer.
TEST(EncodingBatchTest, LargeInstancesComeInPartsOfAtMostOneMebibyte) {
  TestServer t;
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  for (uint32_t vertices : {50'000u, 200'000u}) {
    SCOPED_TRACE(vertices);
    const MeshArrays arrays =
        MakeSyntheticMesh({.vertex_count = vertices, .influences = 2, .normals = true, .seed = 6});
    auto info = t.client->Upload(arrays);
    ASSERT_TRUE(info.ok());
    auto mesh = Mesh::Create(arrays).value();
    grpc::ClientContext context;
    auto stream = stub->StreamSkin(&context);
    uint64_t frame = 0;
    for (v1::Encoding encoding : kEncodings) {
      SCOPED_TRACE(encoding);
      const auto palettes = CrowdPalettes(77, 2, frame);
      ASSERT_TRUE(
          stream->Write(MakeRequest(info->mesh_id(), "sse", frame, 2, encoding, true, palettes)));
      const Answer answer = ReadFrame(*stream, frame, vertices, 2, encoding, true);
      ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
      // 24 bytes a vertex in float32, 12 in the compact ones: whole vertices per MiB.
      const uint32_t per_part = (1u << 20) / (encoding == v1::ENCODING_FLOAT32 ? 24 : 12);
      EXPECT_EQ(answer.parts[0], (vertices + per_part - 1) / per_part);
      for (uint32_t i = 0; i < 2; ++i) {
        ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                          answer.positions[i], answer.normals[i], encoding, answer.bounds[i]);
      }
      ++frame;
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
}

// A packed crowd fills parts of up to 1 MiB with whole instances: 40 instances of 5000
// vertices with normals (60 KB an instance in snorm16, 120 KB in float32) come in 3 and 5
// parts, with the same floats as one part per instance.
TEST(EncodingBatchTest, PackedCrowdsComeInFewPartsWithTheSameVertices) {
  TestServer t;
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 5000, .influences = 2, .normals = true, .seed = 8});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  grpc::ClientContext context;
  auto stream = stub->StreamSkin(&context);
  constexpr uint32_t kCrowd = 40;
  uint64_t frame = 0;
  for (v1::Encoding encoding : kEncodings) {
    SCOPED_TRACE(encoding);
    const auto palettes = CrowdPalettes(77, kCrowd, 0);
    Answer answers[2];
    for (bool pack : {false, true}) {
      ASSERT_TRUE(stream->Write(
          MakeRequest(info->mesh_id(), "sse", frame, kCrowd, encoding, true, palettes, pack)));
      answers[pack] = ReadFrame(*stream, frame, 5000, kCrowd, encoding, true);
      ASSERT_EQ(answers[pack].error, grpc::StatusCode::OK) << answers[pack].message;
      ++frame;
    }
    const uint32_t per_part = (1u << 20) / (5000 * (encoding == v1::ENCODING_FLOAT32 ? 24 : 12));
    EXPECT_EQ(answers[1].messages, (kCrowd + per_part - 1) / per_part);
    EXPECT_EQ(answers[0].messages, kCrowd);
    for (uint32_t i = 0; i < kCrowd; ++i) {
      EXPECT_EQ(answers[1].positions[i], answers[0].positions[i]) << "instance " << i;
      EXPECT_EQ(answers[1].normals[i], answers[0].normals[i]) << "instance " << i;
      EXPECT_EQ(answers[1].bounds[i], answers[0].bounds[i]) << "instance " << i;
      ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                        answers[1].positions[i], answers[1].normals[i], encoding,
                        answers[1].bounds[i]);
    }
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST(EncodingBatchTest, SkinTakesEncodingsAndBatchesToo) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 900, .influences = 4});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  const auto palettes = CrowdPalettes(77, 4, 2);
  grpc::ClientContext context;
  auto reader = stub->Skin(&context, MakeRequest(info->mesh_id(), "serial", 9, 4,
                                                 v1::ENCODING_SNORM16, false, palettes));
  const Answer answer = ReadFrame(*reader, 9, 900, 4, v1::ENCODING_SNORM16, false);
  ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
  EXPECT_TRUE(reader->Finish().ok());
  for (uint32_t i = 0; i < 4; ++i) {
    ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77), answer.positions[i],
                      {}, v1::ENCODING_SNORM16, answer.bounds[i]);
  }
}

TEST(EncodingBatchTest, BadInstancesAreNamedAndTheStreamGoesOn) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 300, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  grpc::ClientContext context;
  auto stream = stub->StreamSkin(&context);
  const auto expect_error = [&](uint64_t frame, uint32_t instances, const std::vector<float>& p,
                                const std::string& expected) {
    ASSERT_TRUE(stream->Write(
        MakeRequest(info->mesh_id(), "sse", frame, instances, v1::ENCODING_FLOAT32, false, p)));
    const Answer answer = ReadFrame(*stream, frame, 300, instances, v1::ENCODING_FLOAT32, false);
    EXPECT_EQ(answer.error, grpc::StatusCode::INVALID_ARGUMENT) << answer.message;
    EXPECT_NE(answer.message.find(expected), std::string::npos) << answer.message;
  };
  const auto expect_good = [&](uint64_t frame, uint32_t instances, v1::Encoding encoding) {
    const auto palettes = CrowdPalettes(77, instances, frame);
    ASSERT_TRUE(stream->Write(
        MakeRequest(info->mesh_id(), "sse", frame, instances, encoding, false, palettes)));
    const Answer answer = ReadFrame(*stream, frame, 300, instances, encoding, false);
    ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
    for (uint32_t i = 0; i < instances; ++i) {
      ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                        answer.positions[i], {}, encoding, answer.bounds[i]);
    }
  };

  expect_good(0, 4, v1::ENCODING_SNORM16);
  // Instance 2 of 4 has a NaN in joint 5.
  auto bad = CrowdPalettes(77, 4, 1);
  bad[2 * 12 * 77 + 5 * 12 + 3] = std::numeric_limits<float>::quiet_NaN();
  expect_error(1, 4, bad, "instance 2: palette[joint 5][row 0, col 3]");
  expect_good(2, 4, v1::ENCODING_FLOAT16);
  // The palette of instance 3 of 5 is cut short.
  auto short_batch = CrowdPalettes(77, 5, 3);
  short_batch.resize(3 * 12 * 77 + 100);
  expect_error(3, 5, short_batch, "instance 3's palette is missing or short");
  // More palettes than instances.
  expect_error(4, 2, CrowdPalettes(77, 3, 4), "more than the 12 * 77 * 2");
  // Over the limit of instances per request.
  expect_error(5, 65, CrowdPalettes(77, 65, 5), "instances = 65 exceeds the limit of 64");
  // float16 overflow names the vertex instead of sending infinity.
  auto far = CrowdPalettes(77, 2, 6);
  for (std::size_t j = 0; j < 77; ++j) far[12 * 77 + j * 12 + 3] = 1e6f;  // instance 1, +x
  ASSERT_TRUE(
      stream->Write(MakeRequest(info->mesh_id(), "sse", 6, 2, v1::ENCODING_FLOAT16, false, far)));
  const Answer overflow = ReadFrame(*stream, 6, 300, 2, v1::ENCODING_FLOAT16, false);
  EXPECT_EQ(overflow.error, grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(overflow.message.find("instance 1: "), std::string::npos) << overflow.message;
  EXPECT_NE(overflow.message.find("vertex 0"), std::string::npos) << overflow.message;
  // An unknown encoding.
  ASSERT_TRUE(stream->Write(MakeRequest(info->mesh_id(), "sse", 7, 1, static_cast<v1::Encoding>(9),
                                        false, CrowdPalettes(77, 1, 7))));
  const Answer unknown = ReadFrame(*stream, 7, 300, 1, v1::ENCODING_FLOAT32, false);
  EXPECT_EQ(unknown.error, grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(unknown.message.find("encoding = 9 is unknown"), std::string::npos) << unknown.message;
  expect_good(8, 3, v1::ENCODING_FLOAT32);  // nothing else on the stream was harmed
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

// SkinRequest.early_parts: a crowd's parts go out as their instances are skinned. Every part
// but the final one leaves before the frame is done, so only the final one carries the
// timings; the values are those of the parts sent after the frame; a frame that fails
// after some parts went out ends with its error part, and the stream goes on.
TEST(EncodingBatchTest, EarlyPartsLeaveBeforeTheFrameIsDoneAndAFailureEndsThem) {
  TestServer t;
  // 100k vertices: 1.2 MB of float32 per instance, two parts each.
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 100'000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  grpc::ClientContext context;
  auto stream = stub->StreamSkin(&context);
  uint64_t frame = 0;
  for (const char* backend : {"serial", "simd-openmp", "opencl"}) {
    for (v1::Encoding encoding : kEncodings) {
      for (bool pack : {false, true}) {
        const uint32_t k = 6;
        const auto palettes = CrowdPalettes(77, k, frame);
        v1::SkinRequest request =
            MakeRequest(info->mesh_id(), backend, frame, k, encoding, false, palettes, pack);
        request.set_early_parts(true);
        // Once for the timings, once for the values.
        ASSERT_TRUE(stream->Write(request));
        v1::SkinResponse part;
        int parts = 0, timed = 0;
        do {
          ASSERT_TRUE(stream->Read(&part));
          ASSERT_FALSE(part.has_error()) << part.error().message();
          ++parts;
          timed += part.has_timing();
        } while (!part.last());
        EXPECT_TRUE(part.has_timing() && part.timing().compute_ns() > 0) << backend;
        EXPECT_EQ(timed, 1) << backend << ": " << parts << " parts, only the final one timed";
        EXPECT_GT(parts, 1);
        request.set_frame(++frame);
        ASSERT_TRUE(stream->Write(request));
        const Answer answer = ReadFrame(*stream, frame, 100'000, k, encoding, false);
        ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
        for (uint32_t i = 0; i < k; ++i) {
          ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                            answer.positions[i], {}, encoding, answer.bounds[i]);
        }
        ++frame;
      }
    }
  }
  // Instance 4 of 6 overflows float16: the parts of 0..3 may be out; its error ends them.
  auto far = CrowdPalettes(77, 6, frame);
  for (std::size_t j = 0; j < 77; ++j) far[4 * 12 * 77 + j * 12 + 3] = 1e6f;
  v1::SkinRequest bad =
      MakeRequest(info->mesh_id(), "serial", frame, 6, v1::ENCODING_FLOAT16, false, far);
  bad.set_early_parts(true);
  ASSERT_TRUE(stream->Write(bad));
  const Answer overflow = ReadFrame(*stream, frame, 100'000, 6, v1::ENCODING_FLOAT16, false);
  EXPECT_EQ(overflow.error, grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(overflow.message.find("instance 4: "), std::string::npos) << overflow.message;
  // The stream goes on, with and without early parts.
  for (bool early : {true, false}) {
    const auto palettes = CrowdPalettes(77, 3, ++frame);
    v1::SkinRequest good =
        MakeRequest(info->mesh_id(), "sse", frame, 3, v1::ENCODING_SNORM16, false, palettes);
    good.set_early_parts(early);
    ASSERT_TRUE(stream->Write(good));
    const Answer answer = ReadFrame(*stream, frame, 100'000, 3, v1::ENCODING_SNORM16, false);
    ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
    for (uint32_t i = 0; i < 3; ++i) {
      ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                        answer.positions[i], {}, v1::ENCODING_SNORM16, answer.bounds[i]);
    }
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

// Skin (one frame per call) with early parts: the parts, then the call's status.
TEST(EncodingBatchTest, SkinTakesEarlyPartsAndEndsAFailedFrameWithItsStatus) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 100'000, .influences = 2});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok());
  auto mesh = Mesh::Create(arrays).value();
  const auto palettes = CrowdPalettes(77, 4, 3);
  client::FrameResult result;
  ASSERT_TRUE(t.client
                  ->Skin(info->mesh_id(), palettes, 3,
                         {.backend = "simd", .instances = 4, .early_parts = true}, &result)
                  .ok());
  EXPECT_GT(result.timing.compute_ns(), 0) << "the final part's timings";
  for (uint32_t i = 0; i < 4; ++i) {
    ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                      result.instance_positions(i), {}, v1::ENCODING_FLOAT32, {});
  }
  auto far = palettes;
  for (std::size_t j = 0; j < 77; ++j) far[3 * 12 * 77 + j * 12 + 3] = 1e6f;
  const Status s = t.client->Skin(info->mesh_id(), far, 4,
                                  {.backend = "simd",
                                   .encoding = VertexEncoding::kFloat16,
                                   .instances = 4,
                                   .early_parts = true},
                                  &result);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("instance 3: "), std::string::npos) << s.message();
}

// A stream takes the frame job freed last for its next frame: answered one frame at a time
// it holds one job's buffers, not one per slot of its window (16 by default), and with
// several frames in flight, jobs reused in another order than the frames', every answer
// is still its own frame's.
TEST(EncodingBatchTest, AStreamReusesTheJobFreedLastAndAnswersEachFrameWithItsOwn) {
  TestServer t;
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 3000, .influences = 2, .seed = 9});
  auto info = t.client->Upload(arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  auto mesh = Mesh::Create(arrays).value();
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  grpc::ClientContext context;
  auto stream = stub->StreamSkin(&context);
  const auto send = [&](uint64_t frame) {
    return stream->Write(MakeRequest(info->mesh_id(), "sse", frame, 3, v1::ENCODING_SNORM16, false,
                                     CrowdPalettes(77, 3, frame)));
  };
  const auto check = [&](uint64_t frame) {
    SCOPED_TRACE(::testing::Message() << "frame " << frame);
    const Answer answer = ReadFrame(*stream, frame, 3000, 3, v1::ENCODING_SNORM16, false);
    ASSERT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
    const auto palettes = CrowdPalettes(77, 3, frame);
    for (uint32_t i = 0; i < 3; ++i) {
      ExpectWithinBound(*mesh, std::span(palettes).subspan(i * 12 * 77, 12 * 77),
                        answer.positions[i], {}, v1::ENCODING_SNORM16, answer.bounds[i]);
    }
  };
  const auto held = [&] {
    auto stats = t.client->GetServerStats();
    EXPECT_TRUE(stats.ok()) << stats.status().ToString();
    return stats.ok() ? stats->inflight_bytes() : 0;
  };
  uint64_t frame = 0;
  ASSERT_TRUE(send(frame));
  check(frame++);
  const uint64_t one_job = held();
  ASSERT_GT(one_job, 0u);
  for (; frame < 20; ++frame) {
    ASSERT_TRUE(send(frame));
    check(frame);
    // Lets the server see its last write done before the next frame arrives.
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // One job; two if a frame ever arrived before the previous one's write was done.
  EXPECT_LE(held(), 2 * one_job) << "one frame in flight at a time grew more than one job";
  for (uint64_t burst : {4, 1, 3, 2, 4, 1}) {
    for (uint64_t b = 0; b < burst; ++b) ASSERT_TRUE(send(frame + b));
    for (uint64_t b = 0; b < burst; ++b) check(frame + b);
    frame += burst;
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST(EncodingBatchTest, FramesBeyondTheInflightBudgetAreRefusedAndTheMemoryReturns) {
  server::ServerOptions options;
  options.inflight_budget_mb = 1;
  TestServer t(options);
  // 100k vertices: 1.2 MB skinned + 1.2 MB encoded, more than the whole budget.
  auto big = t.client->Upload(MakeSyntheticMesh({.vertex_count = 100'000, .influences = 2}));
  auto small = t.client->Upload(MakeSyntheticMesh({.vertex_count = 1000, .influences = 2}));
  ASSERT_TRUE(big.ok() && small.ok());
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  {
    grpc::ClientContext context;
    auto stream = stub->StreamSkin(&context);
    const auto palette = CrowdPalettes(77, 1, 0);
    ASSERT_TRUE(stream->Write(
        MakeRequest(big->mesh_id(), "sse", 0, 1, v1::ENCODING_FLOAT32, false, palette)));
    const Answer refused = ReadFrame(*stream, 0, 100'000, 1, v1::ENCODING_FLOAT32, false);
    EXPECT_EQ(refused.error, grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.message.find("--inflight-budget-mb"), std::string::npos) << refused.message;
    ASSERT_TRUE(stream->Write(
        MakeRequest(small->mesh_id(), "sse", 1, 1, v1::ENCODING_FLOAT32, false, palette)));
    const Answer answered = ReadFrame(*stream, 1, 1000, 1, v1::ENCODING_FLOAT32, false);
    EXPECT_EQ(answered.error, grpc::StatusCode::OK) << answered.message;
    auto stats = t.client->GetServerStats();
    ASSERT_TRUE(stats.ok());
    EXPECT_EQ(stats->inflight_budget_bytes(), 1u << 20);
    EXPECT_GT(stats->inflight_bytes(), 0u) << "the stream's buffers are charged";
    EXPECT_EQ(stats->rejected_inflight_budget(), 1u);
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  // The stream's buffers are given back once it ends.
  uint64_t held = 1;
  for (int i = 0; i < 100 && held != 0; ++i) {
    held = t.client->GetServerStats()->inflight_bytes();
    if (held != 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(held, 0u);
}

// snorm16 on `simd`: the loop keeps the frame's float positions until it has their box, in
// the frame job's buffer (EncodedOutput::box_scratch), which the in-flight budget counts: a
// stream of snorm16 frames holds 12 bytes a vertex more than one of float16 frames (the
// same encoded bytes otherwise), and its answers stay within the encoding's bound.
TEST(EncodingBatchTest, Snorm16OnSimdCountsItsFloatPositionsInTheInflightBudget) {
  TestServer t;
  constexpr uint32_t kVertices = 50'000;
  auto mesh_arrays = MakeSyntheticMesh({.vertex_count = kVertices, .influences = 4});
  auto mesh = Mesh::Create(mesh_arrays);
  auto info = t.client->Upload(mesh_arrays);
  ASSERT_TRUE(mesh.ok() && info.ok());
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  const auto palette = CrowdPalettes(77, 1, 0);
  const auto held_while_streaming = [&](v1::Encoding encoding) -> uint64_t {
    grpc::ClientContext context;
    auto stream = stub->StreamSkin(&context);
    EXPECT_TRUE(
        stream->Write(MakeRequest(info->mesh_id(), "simd", 0, 1, encoding, false, palette)));
    const Answer answer = ReadFrame(*stream, 0, kVertices, 1, encoding, false);
    EXPECT_EQ(answer.error, grpc::StatusCode::OK) << answer.message;
    if (answer.error == grpc::StatusCode::OK) {
      ExpectWithinBound(**mesh, palette, answer.positions[0], {}, encoding, answer.bounds[0]);
    }
    auto stats = t.client->GetServerStats();
    EXPECT_TRUE(stats.ok());
    const uint64_t held = stats.ok() ? stats->inflight_bytes() : 0;
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
    return held;
  };
  const uint64_t float16 = held_while_streaming(v1::ENCODING_FLOAT16);
  // The first stream's buffers are given back before the second one starts.
  for (int i = 0; i < 100 && t.client->GetServerStats()->inflight_bytes() != 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const uint64_t snorm16 = held_while_streaming(v1::ENCODING_SNORM16);
  EXPECT_GE(snorm16, float16 + 12ull * kVertices)
      << "float16 stream held " << float16 << " bytes, snorm16 " << snorm16;
  EXPECT_LE(snorm16, float16 + 12ull * kVertices + 4096);
}

// Answers go to gRPC as slices of the frame job's buffer, which keeps the stream's
// reactor (and so its jobs and budget) alive until gRPC lets go. A stream cut off in the
// middle of a many-part frame must still let go: its buffers return to the budget.
TEST(EncodingBatchTest, AStreamCutOffInTheMiddleOfAFrameGivesItsMemoryBack) {
  TestServer t;
  auto info = t.client->Upload(MakeSyntheticMesh({.vertex_count = 100'000, .influences = 2}));
  ASSERT_TRUE(info.ok());
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  {
    grpc::ClientContext context;
    auto stream = stub->StreamSkin(&context);
    // 8 instances x 1.2 MB of float32: 10 parts of at most 1 MiB.
    ASSERT_TRUE(stream->Write(MakeRequest(info->mesh_id(), "sse", 0, 8, v1::ENCODING_FLOAT32, false,
                                          CrowdPalettes(77, 8, 0))));
    v1::SkinResponse part;
    ASSERT_TRUE(stream->Read(&part));
    EXPECT_FALSE(part.last());
    EXPECT_GT(t.client->GetServerStats()->inflight_bytes(), 0u);
    context.TryCancel();
    EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  uint64_t held = 1, open = 1;
  for (int i = 0; i < 200 && (held != 0 || open != 0); ++i) {
    auto stats = t.client->GetServerStats();
    ASSERT_TRUE(stats.ok());
    held = stats->inflight_bytes();
    open = stats->open_streams();
    if (held != 0 || open != 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(open, 0u);
  EXPECT_EQ(held, 0u) << "the cut-off stream's frame buffers were never given back";
}

}  // namespace
}  // namespace skinserve::testing
