// FrameAssembler and the client library's reuse, against responses built here by hand:
// every encoding decoded within its stated bound, crowd batches reassembled by instance
// and vertex range or packed several whole instances a part, every malformed sequence of
// parts refused naming the frame, instance and range, parts read from gRPC's bytes (any
// slicing, any field order) decoded exactly as parsed ones, and a warm FrameResult filled
// again without one heap allocation.
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#if SKINSERVE_COUNT_ALLOCATIONS
#include "alloc_counter.h"
#endif
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::client {
namespace {

// Random x y z triples per instance, different boxes per instance.
std::vector<std::vector<float>> Instances(uint32_t count, uint32_t vertices, bool normals) {
  std::mt19937 rng(count * 100 + vertices);
  std::vector<std::vector<float>> out(count);
  for (uint32_t k = 0; k < count; ++k) {
    std::uniform_real_distribution<float> u(-1.0f - k, 2.0f + 3 * k);
    for (uint32_t i = 0; i < 3 * vertices; ++i) out[k].push_back(u(rng));
    if (normals) {
      for (uint32_t v = 0; v < vertices; ++v) {
        float* n = &out[k][3 * v];
        const float length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int a = 0; a < 3; ++a) n[a] /= length;
      }
    }
  }
  return out;
}

std::string Bytes(VertexEncoding e, std::span<const float> values, const Bounds& b, bool normals) {
  std::string bytes(values.size() * EncodedBytesPerValue(e), '\0');
  std::span<std::byte> out(reinterpret_cast<std::byte*>(bytes.data()), bytes.size());
  const Status s = normals ? EncodeNormals(e, values, out) : EncodePositions(e, values, b, out);
  EXPECT_TRUE(s.ok()) << s.ToString();
  return bytes;
}

void SetBounds(const Bounds& b, v1::SkinResponse* part) {
  v1::Bounds* w = part->mutable_bounds();
  w->set_min_x(b.min[0]);
  w->set_min_y(b.min[1]);
  w->set_min_z(b.min[2]);
  w->set_max_x(b.max[0]);
  w->set_max_y(b.max[1]);
  w->set_max_z(b.max[2]);
}

// The parts a server sends: per instance, ranges of at most `per_part` vertices, in order.
std::vector<v1::SkinResponse> Parts(uint64_t frame, VertexEncoding e,
                                    const std::vector<std::vector<float>>& positions,
                                    const std::vector<std::vector<float>>* normals,
                                    uint32_t per_part) {
  std::vector<v1::SkinResponse> parts;
  const auto instances = static_cast<uint32_t>(positions.size());
  const auto vertices = static_cast<uint32_t>(positions[0].size() / 3);
  for (uint32_t k = 0; k < instances; ++k) {
    const Bounds box = ComputeBounds(positions[k]).value();
    for (uint32_t first = 0; first < vertices; first += per_part) {
      const uint32_t count = std::min(per_part, vertices - first);
      v1::SkinResponse part;
      part.set_frame(frame);
      part.set_instance(k);
      part.set_instances(instances);
      part.set_first_vertex(first);
      part.set_vertex_count(count);
      part.set_total_vertices(vertices);
      part.set_encoding(static_cast<v1::Encoding>(e));
      part.mutable_timing()->set_compute_ns(1234);
      if (e == VertexEncoding::kSnorm16) SetBounds(box, &part);
      const std::span<const float> range(positions[k].data() + 3 * first, 3 * count);
      part.set_positions(Bytes(e, range, box, false));
      if (normals != nullptr) {
        part.set_normals(Bytes(
            e, std::span<const float>((*normals)[k].data() + 3 * first, 3 * count), box, true));
      }
      parts.push_back(std::move(part));
    }
  }
  parts.back().set_last(true);
  return parts;
}

// The parts a server sends for SkinRequest.pack_instances: `per_part` whole instances per
// part (the last part may hold fewer), each instance's box in instance_bounds.
std::vector<v1::SkinResponse> PackedParts(uint64_t frame, VertexEncoding e,
                                          const std::vector<std::vector<float>>& positions,
                                          const std::vector<std::vector<float>>* normals,
                                          uint32_t per_part) {
  std::vector<v1::SkinResponse> parts;
  const auto instances = static_cast<uint32_t>(positions.size());
  const auto vertices = static_cast<uint32_t>(positions[0].size() / 3);
  for (uint32_t first = 0; first < instances; first += per_part) {
    const uint32_t count = std::min(per_part, instances - first);
    v1::SkinResponse part;
    part.set_frame(frame);
    part.set_instance(first);
    part.set_instance_count(count);
    part.set_instances(instances);
    part.set_vertex_count(vertices);
    part.set_total_vertices(vertices);
    part.set_encoding(static_cast<v1::Encoding>(e));
    std::string p, n;
    for (uint32_t k = first; k < first + count; ++k) {
      const Bounds box = ComputeBounds(positions[k]).value();
      if (e == VertexEncoding::kSnorm16) {
        if (k == first) SetBounds(box, &part);
        v1::SkinResponse holder;
        SetBounds(box, &holder);
        *part.add_instance_bounds() = holder.bounds();
      }
      p += Bytes(e, positions[k], box, false);
      if (normals != nullptr) n += Bytes(e, (*normals)[k], box, true);
    }
    part.set_positions(p);
    part.set_normals(n);
    parts.push_back(std::move(part));
  }
  parts.back().set_last(true);
  return parts;
}

// `part` as gRPC would hold it: serialized, cut into slices of `slice` bytes (so that the
// vertex data's values and triples straddle slice boundaries).
grpc::ByteBuffer Wire(const v1::SkinResponse& part, std::size_t slice) {
  const std::string bytes = part.SerializeAsString();
  std::vector<grpc::Slice> slices;
  for (std::size_t at = 0; at < bytes.size(); at += slice) {
    slices.emplace_back(bytes.data() + at, std::min(slice, bytes.size() - at));
  }
  return grpc::ByteBuffer(slices.data(), slices.size());
}

std::vector<grpc::ByteBuffer> Wire(const std::vector<v1::SkinResponse>& parts, std::size_t slice) {
  std::vector<grpc::ByteBuffer> wire;
  for (const auto& part : parts) wire.push_back(Wire(part, slice));
  return wire;
}

// Feeds every part's bytes through `reader`; true when the frame completed exactly at the
// last one.
bool AssembleRaw(const std::vector<grpc::ByteBuffer>& parts, RawPart* reader, FrameResult* result) {
  FrameAssembler assembler;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const bool done = assembler.Add(parts[i], reader, result);
    if (done != (i + 1 == parts.size())) return false;
  }
  return true;
}

// Feeds every part; returns whether the frame completed exactly at the last one.
bool Assemble(const std::vector<v1::SkinResponse>& parts, FrameResult* result) {
  FrameAssembler assembler;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const bool done = assembler.Add(parts[i], result);
    if (done != (i + 1 == parts.size())) return false;
  }
  return true;
}

TEST(FrameAssemblerTest, EveryEncodingAndCrowdDecodesWithinItsBound) {
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    for (uint32_t instances : {1u, 3u}) {
      const auto positions = Instances(instances, 1001, false);
      const auto normals = Instances(instances, 1001, true);
      const auto parts = Parts(42, e, positions, &normals, 300);  // 4 parts per instance
      FrameResult r;
      ASSERT_TRUE(Assemble(parts, &r));
      ASSERT_TRUE(r.status.ok()) << r.status.ToString();
      EXPECT_EQ(r.frame, 42u);
      EXPECT_EQ(r.instances, instances);
      EXPECT_EQ(r.vertices, 1001u);
      EXPECT_EQ(r.encoding, e);
      EXPECT_EQ(r.timing.compute_ns(), 1234);
      ASSERT_EQ(r.positions.size(), 3u * 1001 * instances);
      for (uint32_t k = 0; k < instances; ++k) {
        const Bounds box = ComputeBounds(positions[k]).value();
        if (e == VertexEncoding::kSnorm16) {
          EXPECT_EQ(r.bounds[k], box);
        }
        const auto p = r.instance_positions(k);
        const auto n = r.instance_normals(k);
        for (std::size_t i = 0; i < p.size(); ++i) {
          const double x = positions[k][i];
          ASSERT_LE(std::fabs(p[i] - x), PositionEncodingError(e, box, i % 3, x))
              << VertexEncodingName(e) << " instance " << k << " value " << i;
          ASSERT_LE(std::fabs(n[i] - normals[k][i]), NormalEncodingError(e, normals[k][i]));
        }
        if (e == VertexEncoding::kFloat32) {
          EXPECT_TRUE(std::equal(p.begin(), p.end(), positions[k].begin()));
        }
      }
    }
  }
}

TEST(FrameAssemblerTest, AServerBeforeCrowdsAndEncodingsStillAssembles) {
  // instances = 0 and encoding unset: one float32 instance, as old servers answer.
  auto parts = Parts(7, VertexEncoding::kFloat32, Instances(1, 10, false), nullptr, 4);
  for (auto& part : parts) part.clear_instances();
  FrameResult r;
  ASSERT_TRUE(Assemble(parts, &r));
  EXPECT_TRUE(r.status.ok()) << r.status.ToString();
  EXPECT_EQ(r.instances, 1u);
  EXPECT_TRUE(r.normals.empty());
}

// Assembles `parts`, expects the frame to fail naming `message`, with empty arrays.
// Refused alike parsed and read from gRPC's bytes (in 5-byte slices).
void ExpectRefused(const std::vector<v1::SkinResponse>& parts, const std::string& message) {
  FrameResult r;
  FrameAssembler assembler;
  for (const auto& part : parts) assembler.Add(part, &r);
  EXPECT_EQ(r.status.code(), StatusCode::kInternal) << message;
  EXPECT_NE(r.status.message().find(message), std::string::npos) << r.status.message();
  EXPECT_TRUE(r.positions.empty());
  FrameResult raw;
  FrameAssembler raw_assembler;
  RawPart reader;
  for (const auto& bytes : Wire(parts, 5)) raw_assembler.Add(bytes, &reader, &raw);
  EXPECT_EQ(raw.status.code(), StatusCode::kInternal) << message;
  EXPECT_EQ(raw.status.message(), r.status.message());
  EXPECT_TRUE(raw.positions.empty());
}

TEST(FrameAssemblerTest, MalformedPartsAreRefusedNamingFrameInstanceAndRange) {
  const auto good =
      Parts(9, VertexEncoding::kSnorm16, Instances(2, 10, false), nullptr, 4);  // 3 per instance
  auto parts = good;
  parts[1].set_vertex_count(9);  // [4, +9) past 10 vertices
  ExpectRefused(parts, "frame 9, instance 0, vertices [4, +9): out of order or out of range");
  parts = good;
  parts.erase(parts.begin() + 1);  // a missing range
  ExpectRefused(parts, "instance 0 vertex 4 was due");
  parts = good;
  std::swap(parts[2], parts[3]);  // instance 1 begins before instance 0 ends
  ExpectRefused(parts, "frame 9, instance 1, vertices [0, +4): out of order");
  parts = good;
  parts[3].set_instance(5);  // beyond the frame's instances
  ExpectRefused(parts, "instance 5");
  parts = good;
  parts[1].set_total_vertices(11);
  ExpectRefused(parts, "does not match its frame's first part");
  parts = good;
  parts[4].set_encoding(v1::ENCODING_FLOAT16);
  ExpectRefused(parts, "does not match its frame's first part");
  parts = good;
  parts[1].set_positions(parts[1].positions().substr(1));
  ExpectRefused(parts, "frame 9, instance 0, vertices [4, +4): positions: 23 bytes, expected 24");
  parts = good;
  parts[2].mutable_bounds()->set_max_y(parts[2].bounds().max_y() + 1);
  ExpectRefused(parts, "bounds differ from the instance's first part");
  parts = good;
  parts[0].mutable_bounds()->set_max_x(INFINITY);
  ExpectRefused(parts, "bounds.max_x");
  parts = good;
  parts[2].set_last(true);  // ends after instance 0 of 2
  parts.resize(3);
  ExpectRefused(parts, "ended at instance 1 vertex 0 of 2 x 10");
  parts = good;
  parts.back().set_last(false);  // complete, but never marked last
  ExpectRefused(parts, "the frame is complete but the part is not marked last");
  parts = good;
  for (auto& part : parts) part.set_encoding(static_cast<v1::Encoding>(7));
  ExpectRefused(parts, "unknown encoding 7");
  parts = good;
  parts[0].set_instances(1u << 30);
  ExpectRefused(parts, "more than the client accepts");
  parts = good;
  parts[3].set_frame(10);
  ExpectRefused(parts, "does not match");
}

// A frame the server says it wrote into the client's region: 2 instances of 10 vertices,
// float32 positions and normals, at offset 64 of a 4 KiB region holding `values`.
struct RegionFrame {
  std::unique_ptr<SharedMemoryRegion> region;
  RegionOutput output;
  v1::SkinResponse part;
};

RegionFrame WrittenRegionFrame(std::span<const float> values) {
  RegionFrame f;
  auto region = SharedMemoryRegion::Create(SharedMemoryRegion::UniqueKey("assembler-test"), 4096);
  EXPECT_TRUE(region.ok()) << region.status().message();
  f.region = std::move(region).value();
  f.output = {.name = "frames", .region = f.region.get(), .offset = 64};
  const wire::RegionLayout layout =
      wire::LayoutInRegion(64, 10, 2, VertexEncoding::kFloat32, /*normals=*/true);
  std::memcpy(f.region->bytes().data() + layout.positions_offset, values.data(),
              layout.instance_bytes * 2);
  std::memcpy(f.region->bytes().data() + layout.normals_offset,
              values.data() + layout.instance_bytes * 2 / sizeof(float), layout.instance_bytes * 2);
  f.part.set_frame(4);
  f.part.set_total_vertices(10);
  f.part.set_instances(2);
  f.part.set_last(true);
  v1::RegionWrite* write = f.part.mutable_region_write();
  write->set_region("frames");
  write->set_positions_offset(layout.positions_offset);
  write->set_normals_offset(layout.normals_offset);
  write->set_instance_bytes(layout.instance_bytes);
  write->set_end_offset(layout.end_offset);
  return f;
}

// The client distrusts the server's RegionWrite: a range that does not lie inside the
// mapping - also one whose end would wrap around 2^64 into a small number - fails the
// frame before anything is read, and a range that fits decodes to the bytes in the region.
TEST(FrameAssemblerTest, RegionRangesOutsideTheMappingFailTheFrameWithoutWrapAround) {
  std::vector<float> values(2 * 2 * 30);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.5f * static_cast<float>(i);
  {
    RegionFrame f = WrittenRegionFrame(values);
    FrameResult r;
    FrameAssembler assembler(&f.output);
    ASSERT_TRUE(assembler.Add(f.part, &r));
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    ASSERT_TRUE(DecodeRegionFrame(&r).ok());
    ASSERT_EQ(r.positions.size(), 60u);
    ASSERT_EQ(r.normals.size(), 60u);
    for (std::size_t i = 0; i < 60; ++i) {
      EXPECT_EQ(r.positions[i], values[i]);
      EXPECT_EQ(r.normals[i], values[60 + i]);
    }
  }
  const auto expect_refused = [&](const std::function<void(v1::SkinResponse*)>& hostile) {
    RegionFrame f = WrittenRegionFrame(values);
    hostile(&f.part);
    FrameResult r;
    FrameAssembler assembler(&f.output);
    assembler.Add(f.part, &r);
    EXPECT_EQ(r.status.code(), StatusCode::kInternal) << f.part.ShortDebugString();
    EXPECT_NE(r.status.message().find("region 'frames'"), std::string::npos) << r.status.message();
    EXPECT_TRUE(r.region_positions.empty());
    EXPECT_TRUE(r.region_normals.empty());
  };
  // An offset whose end wraps: 2^64 - 64 + 480 bytes of the frame ends at 416 mod 2^64,
  // inside the 4 KiB mapping, and every field agrees with the layout computed in 64 bits.
  expect_refused([](v1::SkinResponse* part) {
    const uint64_t offset = ~uint64_t{0} - 63;
    const wire::RegionLayout wrapped =
        wire::LayoutInRegion(offset, 10, 2, VertexEncoding::kFloat32, true);
    v1::RegionWrite* write = part->mutable_region_write();
    write->set_positions_offset(offset);
    write->set_normals_offset(wrapped.normals_offset);
    write->set_end_offset(wrapped.end_offset);
  });
  // Counts whose product wraps: 2^32 - 1 instances of 2^32 - 1 vertices.
  expect_refused([](v1::SkinResponse* part) {
    part->set_instances(~uint32_t{0});
    part->set_total_vertices(~uint32_t{0});
    const wire::RegionLayout wrapped =
        wire::LayoutInRegion(64, ~uint32_t{0}, ~uint32_t{0}, VertexEncoding::kFloat32, true);
    v1::RegionWrite* write = part->mutable_region_write();
    write->set_normals_offset(wrapped.normals_offset);
    write->set_instance_bytes(wrapped.instance_bytes);
    write->set_end_offset(wrapped.end_offset);
  });
  // Plainly past the end of the mapping.
  expect_refused([](v1::SkinResponse* part) {
    const wire::RegionLayout late =
        wire::LayoutInRegion(4096, 10, 2, VertexEncoding::kFloat32, true);
    v1::RegionWrite* write = part->mutable_region_write();
    write->set_positions_offset(4096);
    write->set_normals_offset(late.normals_offset);
    write->set_end_offset(late.end_offset);
  });
}

// Packed parts carry the same bytes as one part per instance: the frames decode alike.
TEST(FrameAssemblerTest, PackedCrowdsDecodeAsInstanceByInstance) {
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    SCOPED_TRACE(VertexEncodingName(e));
    const auto positions = Instances(5, 333, false);
    const auto normals = Instances(5, 333, true);
    FrameResult by_instance, packed;
    ASSERT_TRUE(Assemble(Parts(7, e, positions, &normals, 333), &by_instance));
    ASSERT_TRUE(by_instance.status.ok()) << by_instance.status.ToString();
    for (uint32_t per_part : {2u, 5u}) {  // parts of 2, 2, 1 instances; one part of 5
      const auto parts = PackedParts(7, e, positions, &normals, per_part);
      ASSERT_EQ(parts.size(), per_part == 2 ? 3u : 1u);
      ASSERT_TRUE(Assemble(parts, &packed));
      ASSERT_TRUE(packed.status.ok()) << packed.status.ToString();
      EXPECT_EQ(packed.instances, 5u);
      EXPECT_EQ(packed.positions, by_instance.positions);
      EXPECT_EQ(packed.normals, by_instance.normals);
      EXPECT_EQ(packed.bounds, by_instance.bounds);
    }
  }
}

TEST(FrameAssemblerTest, MalformedPackedPartsAreRefused) {
  const auto good = PackedParts(9, VertexEncoding::kSnorm16, Instances(5, 10, false), nullptr, 2);
  auto parts = good;
  parts[1].set_instance_count(4);  // instances 2..5 of 5
  ExpectRefused(parts, "frame 9, instance 2, vertices [0, +10): out of order or out of range");
  parts = good;
  parts[0].set_first_vertex(1);
  ExpectRefused(parts, "out of order or out of range");
  parts = good;
  parts[0].set_vertex_count(5);  // whole instances only
  ExpectRefused(parts, "out of order or out of range");
  parts = good;
  parts[1].mutable_instance_bounds()->RemoveLast();
  ExpectRefused(parts, "2 instances in the part but 1 instance_bounds");
  parts = good;
  parts[1].set_positions(parts[1].positions().substr(2));
  ExpectRefused(parts,
                "frame 9, instance 2, vertices [0, +10): positions: 118 bytes, expected "
                "120 (60 values of snorm16)");
  parts = good;
  parts[1].mutable_instance_bounds(1)->set_max_x(-INFINITY);
  ExpectRefused(parts, "bounds.max_x");
  parts = good;
  parts.erase(parts.begin() + 1);  // instances 2 and 3 missing
  ExpectRefused(parts, "instance 2 vertex 0 was due");
}

// Read from gRPC's bytes, however they are sliced and whatever the field order, a frame
// decodes to exactly what parsing each part gives.
TEST(FrameAssemblerTest, RawPartsDecodeExactlyAsParsedParts) {
  const auto positions = Instances(3, 1001, false);
  const auto normals = Instances(3, 1001, true);
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    for (bool packed : {false, true}) {
      SCOPED_TRACE(::testing::Message() << VertexEncodingName(e) << (packed ? " packed" : ""));
      const auto parts = packed ? PackedParts(4, e, positions, &normals, 2)
                                : Parts(4, e, positions, &normals, 300);
      FrameResult parsed;
      ASSERT_TRUE(Assemble(parts, &parsed));
      ASSERT_TRUE(parsed.status.ok()) << parsed.status.ToString();
      RawPart reader;
      for (std::size_t slice : {5, 7, 16, 4096, 1 << 20}) {
        FrameResult raw;
        ASSERT_TRUE(AssembleRaw(Wire(parts, slice), &reader, &raw)) << slice;
        ASSERT_TRUE(raw.status.ok()) << raw.status.ToString();
        EXPECT_EQ(raw.positions, parsed.positions) << slice;
        EXPECT_EQ(raw.normals, parsed.normals) << slice;
        EXPECT_EQ(raw.bounds, parsed.bounds) << slice;
        EXPECT_EQ(raw.frame, 4u);
        EXPECT_EQ(raw.timing.compute_ns(), parsed.timing.compute_ns());
      }
      // The vertex fields first and the header after (any order is valid protobuf).
      std::vector<grpc::ByteBuffer> reordered;
      for (const auto& part : parts) {
        std::string bytes;
        {
          google::protobuf::io::StringOutputStream stream(&bytes);
          google::protobuf::io::CodedOutputStream out(&stream);
          for (const auto& [field, value] :
               {std::pair{v1::SkinResponse::kNormalsFieldNumber, &part.normals()},
                std::pair{v1::SkinResponse::kPositionsFieldNumber, &part.positions()}}) {
            out.WriteTag(field << 3 | 2);  // wire type 2: length-delimited
            out.WriteVarint32(static_cast<uint32_t>(value->size()));
            out.WriteString(*value);
          }
        }
        v1::SkinResponse header = part;
        header.clear_positions();
        header.clear_normals();
        bytes += header.SerializeAsString();
        const grpc::Slice slice(bytes.data(), bytes.size());
        reordered.emplace_back(&slice, 1);
      }
      FrameResult raw;
      ASSERT_TRUE(AssembleRaw(reordered, &reader, &raw));
      ASSERT_TRUE(raw.status.ok()) << raw.status.ToString();
      EXPECT_EQ(raw.positions, parsed.positions);
      EXPECT_EQ(raw.normals, parsed.normals);
    }
  }
}

TEST(FrameAssemblerTest, BytesThatAreNoSkinResponseFailTheFrame) {
  const std::string junk = "\x0a\xff\xff\xff\xff\x0f not a message";
  const grpc::Slice slice(junk.data(), junk.size());
  const grpc::ByteBuffer bytes(&slice, 1);
  RawPart reader;
  FrameResult r;
  FrameAssembler assembler;
  EXPECT_TRUE(assembler.Add(bytes, &reader, &r));  // the frame ends: nothing more to trust
  EXPECT_EQ(r.status.code(), StatusCode::kInternal);
  EXPECT_NE(r.status.message().find("is not a skinserve.v1.SkinResponse"), std::string::npos)
      << r.status.message();
}

TEST(FrameAssemblerTest, AnErrorPartFailsTheFrameWithItsCode) {
  v1::SkinResponse part;
  part.set_frame(3);
  part.set_last(true);
  part.mutable_error()->set_code(static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  part.mutable_error()->set_message("instance 2: palette has 11 floats");
  FrameResult r;
  r.positions.assign(30, 1.0f);  // left over from an earlier frame
  FrameAssembler assembler;
  EXPECT_TRUE(assembler.Add(part, &r));
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status.message(), "instance 2: palette has 11 floats");
  EXPECT_TRUE(r.positions.empty());
}

#if SKINSERVE_COUNT_ALLOCATIONS  // see CMakeLists.txt: not in sanitizer builds
TEST(FrameAssemblerTest, AWarmResultIsRefilledWithoutAllocating) {
  const auto positions = Instances(4, 5000, false);
  const auto normals = Instances(4, 5000, true);
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    const auto parts = Parts(1, e, positions, &normals, 2000);
    FrameResult r;
    ASSERT_TRUE(Assemble(parts, &r));  // warm: the vectors reach their size
    const float* data = r.positions.data();
    const uint64_t before = skinserve_alloc_counters()->allocations;
    bool ok = true;
    for (int frame = 0; frame < 10; ++frame) ok = ok && Assemble(parts, &r) && r.status.ok();
    const uint64_t allocations = skinserve_alloc_counters()->allocations - before;
    EXPECT_TRUE(ok) << r.status.ToString();
    EXPECT_EQ(allocations, 0u) << VertexEncodingName(e);
    EXPECT_EQ(r.positions.data(), data);
  }
  // From gRPC's bytes through a warm reader: nothing either.
  for (VertexEncoding e :
       {VertexEncoding::kFloat32, VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    const auto wire = Wire(Parts(1, e, positions, &normals, 2000), 16384);
    FrameResult r;
    RawPart reader;
    ASSERT_TRUE(AssembleRaw(wire, &reader, &r));
    const uint64_t before = skinserve_alloc_counters()->allocations;
    bool ok = true;
    for (int frame = 0; frame < 10; ++frame) {
      ok = ok && AssembleRaw(wire, &reader, &r) && r.status.ok();
    }
    const uint64_t allocations = skinserve_alloc_counters()->allocations - before;
    EXPECT_TRUE(ok) << r.status.ToString();
    EXPECT_EQ(allocations, 0u) << "raw " << VertexEncodingName(e);
  }
  // The counter does count: a fresh result allocates.
  const uint64_t before = skinserve_alloc_counters()->allocations;
  FrameResult fresh;
  ASSERT_TRUE(Assemble(Parts(1, VertexEncoding::kFloat32, positions, nullptr, 2000), &fresh));
  EXPECT_GT(skinserve_alloc_counters()->allocations - before, 0u);
}

TEST(FrameAssemblerTest, PaletteIntoAReusedRequestAllocatesOnce) {
  const std::vector<float> palette(12 * 77 * 16, 0.5f);
  v1::SkinRequest request;
  wire::EncodeFloats(palette, request.mutable_palette());
  ASSERT_EQ(request.palette().size(), palette.size() * 4);
  EXPECT_EQ(std::memcmp(request.palette().data(), palette.data(), request.palette().size()), 0);
  const uint64_t before = skinserve_alloc_counters()->allocations;
  for (int i = 0; i < 10; ++i) wire::EncodeFloats(palette, request.mutable_palette());
  EXPECT_EQ(skinserve_alloc_counters()->allocations - before, 0u);
}

#endif  // SKINSERVE_COUNT_ALLOCATIONS

TEST(PaletteSourceTest, ViewsStayValidUntilTheNextCall) {
  const std::vector<std::vector<float>> palettes = {{1, 2, 3}, {4, 5}};
  // A reference: a view of the caller's storage, no copy.
  PaletteSource by_reference(
      [&](uint64_t f) -> const std::vector<float>& { return palettes[f % 2]; });
  EXPECT_EQ(by_reference(1).data(), palettes[1].data());
  // A vector by value: kept by the source until the next call.
  PaletteSource by_value([](uint64_t f) { return std::vector<float>(f + 1, 7.0f); });
  const std::span<const float> view = by_value(2);
  ASSERT_EQ(view.size(), 3u);
  EXPECT_EQ(view[2], 7.0f);
}

}  // namespace
}  // namespace skinserve::client
