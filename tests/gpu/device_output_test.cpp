// The `opencl` backend's device path for GPU regions, on whatever OpenCL device the tests
// get (PoCL here and in CI): frames written into device memory at their offsets (memory of
// the runtime's own standing in for an import, which PoCL cannot do), checked against the
// float64 reference with nothing outside the ranges touched, in float32 and in the encodings
// the backend writes itself (decoded within the encoding's bound; a value the encoding
// refuses fails the frame and writes nothing); the import refused with the
// missing extension named; the engine's range and backend checks of device output.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstring>
#include <thread>
#include <vector>

#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_device_memory.h"
#include "backends/opencl/opencl_semaphore.h"
#include "backends/opencl/opencl_tick_launch.h"
#include "device_output_checks.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/engine/engine.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

constexpr uint8_t kCanary = 0xA5;

struct OpenCl {
  std::shared_ptr<OpenClRuntime> runtime;
  std::vector<std::unique_ptr<Backend>> backends;  // opencl, opencl-zerocopy
};

// One runtime for the file: `staging` forces the discrete-GPU path (pinned, lanes).
OpenCl& TestOpenCl(bool staging) {
  static OpenCl direct, staged;
  OpenCl& cl = staging ? staged : direct;
  if (cl.runtime == nullptr) {
    auto runtime = OpenClRuntime::Create({.threads = 2, .force_staging = staging});
    EXPECT_TRUE(runtime.ok()) << runtime.status().ToString();
    if (!runtime.ok()) std::abort();
    cl.runtime = *runtime;
    cl.backends = MakeOpenClBackendsOn(cl.runtime);
  }
  return cl;
}

std::shared_ptr<const Mesh> TestMesh(uint32_t vertices) {
  auto mesh = Mesh::Create(MakeSyntheticMesh(
      {.vertex_count = vertices, .influences = 4, .normals = true, .tangents = true, .seed = 11}));
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return *mesh;
}

std::vector<uint8_t> ReadBack(OpenClRuntime& runtime, const DeviceMemory& memory) {
  std::vector<uint8_t> bytes(memory.byte_size());
  cl_command_queue queue = runtime.AcquireLane()->compute;
  EXPECT_EQ(clEnqueueReadBuffer(queue, OpenClDeviceMemoryBuffer(memory), CL_TRUE, 0, bytes.size(),
                                bytes.data(), 0, nullptr, nullptr),
            CL_SUCCESS);
  return bytes;
}

void Fill(OpenClRuntime& runtime, const DeviceMemory& memory) {
  std::vector<uint8_t> canary(memory.byte_size(), kCanary);
  cl_command_queue queue = runtime.AcquireLane()->compute;
  ASSERT_EQ(clEnqueueWriteBuffer(queue, OpenClDeviceMemoryBuffer(memory), CL_TRUE, 0, canary.size(),
                                 canary.data(), 0, nullptr, nullptr),
            CL_SUCCESS);
}

std::vector<float> FloatsAt(const std::vector<uint8_t>& bytes, uint64_t offset, std::size_t n) {
  std::vector<float> out(n);
  std::memcpy(out.data(), bytes.data() + offset, n * sizeof(float));
  return out;
}

// The bytes outside every [offset, offset + length) range that differ from the canary.
std::size_t TouchedOutside(const std::vector<uint8_t>& bytes,
                           const std::vector<std::pair<uint64_t, uint64_t>>& ranges) {
  std::size_t touched = 0;
  for (uint64_t i = 0; i < bytes.size(); ++i) {
    bool inside = false;
    for (const auto& [offset, length] : ranges)
      inside = inside || (i >= offset && i < offset + length);
    if (!inside && bytes[i] != kCanary) ++touched;
  }
  return touched;
}

class DeviceOutputTest : public ::testing::TestWithParam<bool> {};

void WriteFramesAtOffsets(OpenCl& cl, bool aligned);

// Offsets that are multiples of the device's base-address alignment are written in place by
// the kernel (sub-buffers), the others through the lane's buffers and copies: both right,
// and nothing outside the frame's ranges.
TEST_P(DeviceOutputTest, WritesTheFrameAtItsOffsetsAndNothingElse) {
  OpenCl& cl = TestOpenCl(GetParam());
  for (bool aligned : {false, true}) {
    SCOPED_TRACE(aligned ? "offsets aligned: in place" : "offsets not aligned: copies");
    WriteFramesAtOffsets(cl, aligned);
  }
}

void WriteFramesAtOffsets(OpenCl& cl, bool aligned) {
  Backend& backend = *cl.backends[0];
  ASSERT_EQ(backend.info().id, "opencl");
  ASSERT_TRUE(backend.info().available) << backend.info().unavailable_reason;
  const uint32_t v = 3000;  // not a multiple of the kernels' work-group
  auto mesh = TestMesh(v);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  // Positions, normals and tangents with gaps between them: at 192 and 64 or 128 bytes
  // apart, or each at a multiple of the alignment with a gap of one alignment.
  const uint64_t a = cl.runtime->base_address_alignment();
  ASSERT_GT(a, 4u) << "no offset of a float32 array would be misaligned";
  const auto up = [a](uint64_t x) { return (x + a - 1) / a * a; };
  const uint64_t positions = aligned ? 2 * a : 192,
                 normals = aligned ? up(positions + 12ull * v) + a : positions + 12ull * v + 64,
                 tangents = aligned ? up(normals + 12ull * v) + a : normals + 12ull * v + 128,
                 end = tangents + 16ull * v;
  ASSERT_EQ(aligned, positions % a == 0 && normals % a == 0 && tangents % a == 0);
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", end + 256, /*in_place=*/true);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  const uint64_t in_place_before = InPlaceDeviceFrames();
  for (uint64_t frame = 0; frame < 3; ++frame) {
    Fill(*cl.runtime, **memory);
    const auto palette = MakeSyntheticPalette(mesh->joint_count(), 5, frame);
    SkinFrame f{.palette = palette};
    f.device = {.memory = memory->get(),
                .positions_offset = positions,
                .normals_offset = normals,
                .tangents_offset = tangents,
                .normals = true,
                .tangents = true};
    ASSERT_TRUE(f.Validate(*mesh).ok());
    Status s = backend.Skin(**prepared, f);
    ASSERT_TRUE(s.ok()) << s.ToString();
    const std::vector<uint8_t> bytes = ReadBack(*cl.runtime, **memory);
    const auto p = FloatsAt(bytes, positions, 3ull * v), n = FloatsAt(bytes, normals, 3ull * v),
               t = FloatsAt(bytes, tangents, 4ull * v);
    const Deviation d = CompareWithReference(*mesh, palette, p, n, SkinningMethod::kLinear, {}, t);
    EXPECT_TRUE(d.within_tolerance())
        << "frame " << frame << ": position error " << d.max_position_error << " (tolerance "
        << d.position_tolerance << "), normal " << d.max_normal_error << ", tangent "
        << d.max_tangent_error << " at vertex " << d.worst_vertex;
    EXPECT_EQ(TouchedOutside(bytes,
                             {{positions, 12ull * v}, {normals, 12ull * v}, {tangents, 16ull * v}}),
              0u)
        << "bytes outside the frame's ranges were written";
  }
  EXPECT_EQ(InPlaceDeviceFrames() - in_place_before, aligned ? 3u : 0u);
}

// The in-place path keeps a sub-buffer per range of the memory (SubBuffer): frames that
// alternate between two ranges of the same size each land in their own, every time.
TEST_P(DeviceOutputTest, FramesAlternatingBetweenRangesEachLandInTheirOwn) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  ASSERT_TRUE(backend.info().available) << backend.info().unavailable_reason;
  const uint32_t v = 1000;
  auto mesh = TestMesh(v);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const uint64_t a = cl.runtime->base_address_alignment();
  const uint64_t first = a, second = (first + 12ull * v + a - 1) / a * a + a;
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", second + 12ull * v + a, true);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  const uint64_t in_place_before = InPlaceDeviceFrames();
  for (uint64_t frame = 0; frame < 5; ++frame) {
    const uint64_t offset = frame % 2 == 0 ? first : second;
    Fill(*cl.runtime, **memory);
    const auto palette = MakeSyntheticPalette(mesh->joint_count(), 9, frame);
    SkinFrame f{.palette = palette};
    f.device = {.memory = memory->get(), .positions_offset = offset};
    Status s = backend.Skin(**prepared, f);
    ASSERT_TRUE(s.ok()) << s.ToString();
    const std::vector<uint8_t> bytes = ReadBack(*cl.runtime, **memory);
    const Deviation d = CompareWithReference(*mesh, palette, FloatsAt(bytes, offset, 3ull * v), {},
                                             SkinningMethod::kLinear);
    EXPECT_TRUE(d.within_tolerance())
        << "frame " << frame << " at " << offset << ": position error " << d.max_position_error;
    EXPECT_EQ(TouchedOutside(bytes, {{offset, 12ull * v}}), 0u) << "frame " << frame;
  }
  EXPECT_EQ(InPlaceDeviceFrames() - in_place_before, 5u);
}

TEST_P(DeviceOutputTest, EachEncodingAtItsOffsetsDecodesWithinItsBound) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  const uint32_t v = 3001;  // not a multiple of the encoder's work-group
  auto mesh = TestMesh(v);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  for (VertexEncoding encoding : {VertexEncoding::kFloat16, VertexEncoding::kSnorm16}) {
    const uint64_t array = EncodedBytes(encoding, v), tangent = EncodedTangentBytes(encoding, v);
    const uint64_t positions = 96, normals = positions + array + 40,
                   tangents = normals + array + 24;
    auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", tangents + tangent + 128);
    ASSERT_TRUE(memory.ok()) << memory.status().ToString();
    for (uint64_t frame = 0; frame < 2; ++frame) {
      SCOPED_TRACE(::testing::Message() << VertexEncodingName(encoding) << " frame " << frame);
      Fill(*cl.runtime, **memory);
      const auto palette = MakeSyntheticPalette(mesh->joint_count(), 5, frame);
      Bounds box{{NAN, NAN, NAN}, {NAN, NAN, NAN}};
      SkinFrame f{.palette = palette};
      f.device = {.memory = memory->get(),
                  .positions_offset = positions,
                  .normals_offset = normals,
                  .tangents_offset = tangents,
                  .normals = true,
                  .tangents = true,
                  .encoding = encoding,
                  .bounds = &box};
      ASSERT_TRUE(f.Validate(*mesh).ok());
      Status s = backend.Skin(**prepared, f);
      ASSERT_TRUE(s.ok()) << s.ToString();
      const std::vector<uint8_t> bytes = ReadBack(*cl.runtime, **memory);
      const auto at = [&](uint64_t offset, uint64_t n) {
        return std::span<const std::byte>(reinterpret_cast<const std::byte*>(bytes.data()) + offset,
                                          n);
      };
      if (encoding != VertexEncoding::kSnorm16) box = Bounds{};
      std::vector<float> p(3ull * v), n(3ull * v), t(4ull * v);
      ASSERT_TRUE(DecodePositions(encoding, at(positions, array), box, p).ok());
      ASSERT_TRUE(DecodeNormals(encoding, at(normals, array), n).ok());
      ASSERT_TRUE(DecodeTangents(encoding, at(tangents, tangent), t).ok());
      const EncodedDeviation d = CompareEncodedWithReference(*mesh, palette, encoding, box, p, n);
      EXPECT_TRUE(d.within_tolerance())
          << "position ratio " << d.worst_position_ratio << ", normal ratio "
          << d.worst_normal_ratio << " at vertex " << d.worst_vertex;
      EXPECT_EQ(TangentValuesOutsideBound(encoding, t, ReferenceSkin(*mesh, palette).tangents), 0u)
          << "tangent values outside float32 + the encoding's bound";
      EXPECT_EQ(TouchedOutside(bytes, {{positions, array}, {normals, array}, {tangents, tangent}}),
                0u)
          << "bytes outside the frame's ranges were written";
    }
  }
}

// float16 holds at most 65504: the frame fails naming the vertex, as the host encoder
// does, and nothing of it reaches the memory.
TEST_P(DeviceOutputTest, AValueTheEncodingRefusesFailsTheFrameAndWritesNothing) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  const uint32_t v = 700;
  auto mesh = TestMesh(v);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", 4096 + 12ull * v);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  Fill(*cl.runtime, **memory);
  auto palette = MakeSyntheticPalette(mesh->joint_count(), 9, 2);
  for (uint32_t j = 0; j < mesh->joint_count(); ++j) palette[12 * j + 7] = 1e6f;  // y + 1e6
  SkinFrame f{.palette = palette};
  f.device = {.memory = memory->get(),
              .positions_offset = 64,
              .normals_offset = 64 + 6ull * v,
              .normals = true,
              .encoding = VertexEncoding::kFloat16};
  ASSERT_TRUE(f.Validate(*mesh).ok());
  const Status s = backend.Skin(**prepared, f);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  EXPECT_NE(s.message().find("positions[vertex 0][y]"), std::string::npos) << s.ToString();
  EXPECT_EQ(TouchedOutside(ReadBack(*cl.runtime, **memory), {}), 0u)
      << "a refused frame wrote into the memory";
}

// A tick's characters into one memory (Backend::SkinFrames: enqueued on one queue,
// one wait): meshes of different sizes, normals and tangents or not, dual quaternions, an
// encoded frame among them (skinned on its own) and one that fails alone. The linear
// float32 ones run in a tick launch (opencl_tick_launch.h), the others frame by frame.
TEST_P(DeviceOutputTest, FramesSkinnedTogetherEachAtItsOffsets) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  const uint32_t sizes[] = {3001, 700, 1500, 2048, 999};
  std::vector<std::shared_ptr<const Mesh>> meshes;
  std::vector<std::unique_ptr<PreparedMesh>> prepared_meshes;
  std::vector<const PreparedMesh*> prepared;
  for (uint32_t v : sizes) {
    meshes.push_back(TestMesh(v));
    auto p = backend.Prepare(meshes.back());
    ASSERT_TRUE(p.ok()) << p.status().ToString();
    prepared.push_back(p->get());
    prepared_meshes.push_back(std::move(p).value());
  }
  // Character c's arrays one after another, 64 bytes apart.
  struct Range {
    uint64_t positions, normals, tangents;
  };
  // Characters 0 and 2's arrays at multiples of the base-address alignment (2, a dual
  // quaternion frame, runs per frame: written in place), the others' not (per frame: copied
  // from the lane's buffers; in a tick launch: written where they are).
  std::vector<Range> ranges;
  const uint64_t a = cl.runtime->base_address_alignment();
  const auto up = [a](uint64_t x) { return (x + a - 1) / a * a; };
  uint64_t end = 128;
  for (uint32_t v : sizes) {
    Range r{end, end + 12ull * v + 64, end + 24ull * v + 128};
    if (ranges.size() == 0 || ranges.size() == 2) {
      r.positions = up(end);
      r.normals = up(r.positions + 12ull * v) + a;
      r.tangents = up(r.normals + 12ull * v) + a;
    } else if (r.positions % a == 0) {
      r.positions += 4, r.normals += 4, r.tangents += 4;  // keep the others misaligned
    }
    ranges.push_back(r);
    end = r.tangents + 16ull * v + 64;
  }
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", end, /*in_place=*/true);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  Fill(*cl.runtime, **memory);
  std::vector<std::vector<float>> palettes;
  std::vector<SkinFrame> frames;
  Bounds box;
  for (std::size_t c = 0; c < meshes.size(); ++c) {
    palettes.push_back(MakeSyntheticPalette(meshes[c]->joint_count(), 5, c));
    SkinFrame f{.palette = palettes.back()};
    f.device = {.memory = memory->get(),
                .positions_offset = ranges[c].positions,
                .normals_offset = ranges[c].normals,
                .tangents_offset = ranges[c].tangents,
                .normals = c != 1,
                .tangents = c == 0 || c == 3};
    if (c == 2) f.method = SkinningMethod::kDualQuaternion;  // the synthetic palette is rigid
    if (c == 3) f.device.tangents_offset = end;  // fails alone: its tangents are past the end
    if (c == 4) {
      f.device.encoding = VertexEncoding::kSnorm16;
      f.device.bounds = &box;
    }
    frames.push_back(f);
  }
  // The range check is the engine's (CheckDeviceRequest); here the backend must refuse
  // the write itself, without harm to the others.
  std::vector<Status> statuses(frames.size());
  const uint64_t in_place_before = InPlaceDeviceFrames(), ticked_before = TickLaunchFrames();
  backend.SkinFrames(prepared, frames, statuses);
  EXPECT_EQ(InPlaceDeviceFrames() - in_place_before, 1u) << "character 2 only";
  EXPECT_EQ(TickLaunchFrames() - ticked_before, 2u) << "characters 0 and 1";
  const std::vector<uint8_t> bytes = ReadBack(*cl.runtime, **memory);
  std::size_t checked = 0;
  for (std::size_t c = 0; c < meshes.size(); ++c) {
    SCOPED_TRACE(::testing::Message() << "character " << c);
    if (c == 3) {
      EXPECT_FALSE(statuses[c].ok());
      continue;
    }
    ASSERT_TRUE(statuses[c].ok()) << statuses[c].ToString();
    const uint32_t v = sizes[c];
    const Mesh& mesh = *meshes[c];
    if (c == 4) {
      const auto* base = reinterpret_cast<const std::byte*>(bytes.data());
      std::vector<float> p(3ull * v), n(3ull * v);
      ASSERT_TRUE(
          DecodePositions(VertexEncoding::kSnorm16, {base + ranges[c].positions, 6ull * v}, box, p)
              .ok());
      ASSERT_TRUE(
          DecodeNormals(VertexEncoding::kSnorm16, {base + ranges[c].normals, 6ull * v}, n).ok());
      EXPECT_TRUE(
          CompareEncodedWithReference(mesh, palettes[c], VertexEncoding::kSnorm16, box, p, n)
              .within_tolerance());
      ++checked;
      continue;
    }
    const auto p = FloatsAt(bytes, ranges[c].positions, 3ull * v);
    const auto n = frames[c].device.normals ? FloatsAt(bytes, ranges[c].normals, 3ull * v)
                                            : std::vector<float>();
    const auto t = frames[c].device.tangents ? FloatsAt(bytes, ranges[c].tangents, 4ull * v)
                                             : std::vector<float>();
    const Deviation d = CompareWithReference(mesh, palettes[c], p, n, frames[c].method, {}, t);
    EXPECT_TRUE(d.within_tolerance()) << "position error " << d.max_position_error << ", normal "
                                      << d.max_normal_error << " at vertex " << d.worst_vertex;
    ++checked;
  }
  EXPECT_EQ(checked, 4u);
  // Nothing outside the characters' ranges (the failed one wrote nothing past the memory).
  std::vector<std::pair<uint64_t, uint64_t>> written;
  for (std::size_t c = 0; c < ranges.size(); ++c) {
    const uint64_t array = (c == 4 ? 6ull : 12ull) * sizes[c];
    written.insert(written.end(), {{ranges[c].positions, array},
                                   {ranges[c].normals, array},
                                   {ranges[c].tangents, 16ull * sizes[c]}});
  }
  EXPECT_EQ(TouchedOutside(bytes, written), 0u)
      << "bytes outside the characters' ranges were written";
}

// Plain memory (CreateOpenClDeviceMemory without in_place, as the benchmark makes it) takes
// the copies even at aligned offsets: NVIDIA's driver is slow with sub-buffers of it.
TEST_P(DeviceOutputTest, PlainMemoryIsWrittenThroughCopiesEvenWhenAligned) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  const uint32_t v = 2048;
  auto mesh = TestMesh(v);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", 12ull * v);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  const auto palette = MakeSyntheticPalette(mesh->joint_count(), 3, 1);
  SkinFrame f{.palette = palette};
  f.device = {.memory = memory->get(), .positions_offset = 0};
  const uint64_t in_place_before = InPlaceDeviceFrames();
  ASSERT_TRUE(backend.Skin(**prepared, f).ok());
  EXPECT_EQ(InPlaceDeviceFrames(), in_place_before);
  const auto p = FloatsAt(ReadBack(*cl.runtime, **memory), 0, 3ull * v);
  EXPECT_TRUE(CompareWithReference(*mesh, palette, p, {}).within_tolerance());
}

// Batches from two threads (two lanes) into one memory at once, rounds after rounds (each
// memory is held by one batch at a time: DeviceOutputBatch): every character lands at its
// own offsets whatever the interleaving.
TEST_P(DeviceOutputTest, ConcurrentBatchesIntoOneMemoryEachAtItsOffsets) {
  OpenCl& cl = TestOpenCl(GetParam());
  Backend& backend = *cl.backends[0];
  constexpr uint32_t kVertices = 1200;
  constexpr int kThreads = 2, kCharacters = 4, kRounds = 5;
  const uint64_t a = cl.runtime->base_address_alignment();
  const uint64_t array = (12ull * kVertices + a - 1) / a * a;  // aligned: written in place
  auto mesh = TestMesh(kVertices);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  auto memory = CreateOpenClDeviceMemory(*cl.runtime, "opencl", 2 * array * kThreads * kCharacters,
                                         /*in_place=*/true);
  ASSERT_TRUE(memory.ok()) << memory.status().ToString();
  for (int round = 0; round < kRounds; ++round) {
    Fill(*cl.runtime, **memory);
    std::vector<std::vector<float>> palettes(kThreads * kCharacters);
    for (std::size_t c = 0; c < palettes.size(); ++c) {
      palettes[c] = MakeSyntheticPalette(mesh->joint_count(), 30 + round, c);
    }
    std::vector<std::thread> threads;
    std::vector<Status> statuses(palettes.size());
    for (int t = 0; t < kThreads; ++t) {
      threads.emplace_back([&, t] {
        std::vector<SkinFrame> frames;
        for (int k = 0; k < kCharacters; ++k) {
          const std::size_t c = t * kCharacters + k;
          SkinFrame f{.palette = palettes[c]};
          f.device = {.memory = memory->get(),
                      .positions_offset = 2 * array * c,
                      .normals_offset = 2 * array * c + array,
                      .normals = true};
          frames.push_back(f);
        }
        const std::vector<const PreparedMesh*> meshes(kCharacters, prepared->get());
        backend.SkinFrames(meshes, frames,
                           std::span(statuses).subspan(t * kCharacters, kCharacters));
      });
    }
    for (auto& thread : threads) thread.join();
    const std::vector<uint8_t> bytes = ReadBack(*cl.runtime, **memory);
    for (std::size_t c = 0; c < palettes.size(); ++c) {
      SCOPED_TRACE(::testing::Message() << "round " << round << ", character " << c);
      ASSERT_TRUE(statuses[c].ok()) << statuses[c].ToString();
      const auto p = FloatsAt(bytes, 2 * array * c, 3ull * kVertices);
      const auto n = FloatsAt(bytes, 2 * array * c + array, 3ull * kVertices);
      EXPECT_TRUE(CompareWithReference(*mesh, palettes[c], p, n).within_tolerance());
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Paths, DeviceOutputTest, ::testing::Values(false, true),
                         [](const auto& param) { return param.param ? "staged" : "direct"; });

TEST(DeviceImportTest, RefusedNamingWhatTheDeviceLacks) {
  OpenCl& cl = TestOpenCl(false);
  const int fd = memfd_create("not-gpu-memory", MFD_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(ftruncate(fd, 1 << 20), 0);
  auto memory = cl.backends[0]->ImportDeviceMemory({.fd = fd, .byte_size = 1 << 20});
  ASSERT_FALSE(memory.ok());
  EXPECT_EQ(memory.status().code(), StatusCode::kFailedPrecondition);
  std::size_t size = 0;
  clGetDeviceInfo(cl.runtime->device(), CL_DEVICE_EXTENSIONS, 0, nullptr, &size);
  std::string extensions(size, '\0');
  clGetDeviceInfo(cl.runtime->device(), CL_DEVICE_EXTENSIONS, size, extensions.data(), nullptr);
  if (extensions.find("cl_khr_external_memory_opaque_fd") == std::string::npos) {
    // PoCL: the extension is named.
    EXPECT_NE(memory.status().message().find("lacks cl_khr_external_memory"), std::string::npos)
        << memory.status().message();
  } else {
    // A device that imports: the all-zero UUID is not its own.
    EXPECT_NE(memory.status().message().find("is not the opencl backend's device"),
              std::string::npos)
        << memory.status().message();
  }
  close(fd);  // refused: still ours
  // Any other backend cannot import at all.
  auto other = cl.backends[1]->ImportDeviceMemory({.fd = -1, .byte_size = 64});
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(other.status().message().find("backend 'opencl-zerocopy' cannot write into GPU memory"),
            std::string::npos)
      << other.status().message();
}

TEST(DeviceImportTest, ExtensionsAreNamedInTheOrderTheyAreChecked) {
  const std::string memory =
      "cl_khr_icd cl_khr_external_memory cl_khr_external_memory_opaque_fd cl_khr_device_uuid";
  EXPECT_STREQ(MissingImportExtension("", false), "cl_khr_external_memory");
  // A longer name that starts with the one needed is not it.
  EXPECT_STREQ(MissingImportExtension("cl_khr_external_memory_opaque_fd cl_khr_device_uuid", false),
               "cl_khr_external_memory");
  EXPECT_STREQ(MissingImportExtension("cl_khr_external_memory cl_khr_device_uuid", false),
               "cl_khr_external_memory_opaque_fd");
  EXPECT_EQ(MissingImportExtension(memory, false), nullptr);
  EXPECT_STREQ(MissingImportExtension(memory, true), "cl_khr_semaphore");
  EXPECT_STREQ(MissingImportExtension(memory + " cl_khr_semaphore", true),
               "cl_khr_external_semaphore");
  EXPECT_STREQ(MissingImportExtension(memory + " cl_khr_semaphore cl_khr_external_semaphore", true),
               "cl_khr_external_semaphore_opaque_fd");
  // What NVIDIA's OpenCL on the H200 lists (docs/serving/gpu-regions.md).
  EXPECT_EQ(MissingImportExtension(memory + " cl_khr_semaphore cl_khr_external_semaphore "
                                            "cl_khr_external_semaphore_opaque_fd",
                                   true),
            nullptr);
}

TEST(DeviceImportTest, WithASemaphoreRefusedNamingWhatTheDeviceLacksAndBothFdsStayOurs) {
  OpenCl& cl = TestOpenCl(false);
  const int fd = memfd_create("not-gpu-memory", MFD_CLOEXEC);
  const int semaphore = memfd_create("not-a-semaphore", MFD_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_GE(semaphore, 0);
  ASSERT_EQ(ftruncate(fd, 1 << 20), 0);
  auto memory = cl.backends[0]->ImportDeviceMemory(
      {.fd = fd, .byte_size = 1 << 20, .semaphore_fd = semaphore});
  ASSERT_FALSE(memory.ok());
  EXPECT_EQ(memory.status().code(), StatusCode::kFailedPrecondition);
  std::size_t size = 0;
  clGetDeviceInfo(cl.runtime->device(), CL_DEVICE_EXTENSIONS, 0, nullptr, &size);
  std::string extensions(size, '\0');
  clGetDeviceInfo(cl.runtime->device(), CL_DEVICE_EXTENSIONS, size, extensions.data(), nullptr);
  while (!extensions.empty() && extensions.back() == '\0') extensions.pop_back();
  const char* missing = MissingImportExtension(extensions, true);
  if (missing != nullptr) {  // PoCL: the first extension it lacks is named
    EXPECT_NE(memory.status().message().find(
                  fmt::format("cannot import GPU memory with a semaphore: it lacks {} ", missing)),
              std::string::npos)
        << memory.status().message();
  }
  // Refused: both descriptors are still open and ours to close.
  EXPECT_EQ(close(fd), 0);
  EXPECT_EQ(close(semaphore), 0);
}

class FakeMemory final : public DeviceMemory {
 public:
  FakeMemory(uint64_t bytes, std::string backend) : bytes_(bytes), backend_(std::move(backend)) {}
  uint64_t byte_size() const override { return bytes_; }
  const std::string& backend() const override { return backend_; }

 private:
  uint64_t bytes_;
  std::string backend_;
};

TEST(DeviceRequestCheckTest, RangesAndBackend) {
  auto mesh = TestMesh(1000);
  const uint64_t array = 12000, need = 2 * array + 64;  // 2 instances, positions only
  FakeMemory memory(need, "opencl");
  BackendInfo opencl{.id = "opencl"};
  SkinRequest request;
  request.instances = 2;
  request.device = {.memory = &memory, .positions_offset = 64, .instance_bytes = array};
  EXPECT_TRUE(CheckDeviceRequest(request, *mesh, 2, opencl).ok());
  request.device.positions_offset = 128;  // the second instance's last 64 bytes stick out
  Status s = CheckDeviceRequest(request, *mesh, 2, opencl);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("instance 1's output"), std::string::npos) << s.message();
  request.device.positions_offset = UINT64_MAX - 8;  // no wrap-around
  EXPECT_EQ(CheckDeviceRequest(request, *mesh, 2, opencl).code(), StatusCode::kInvalidArgument);
  request.device.positions_offset = 64;
  request.device.instance_bytes = array - 4;  // instances would overlap
  EXPECT_EQ(CheckDeviceRequest(request, *mesh, 2, opencl).code(), StatusCode::kInvalidArgument);
  request.device.instance_bytes = array;
  request.device.normals = true;  // normals past the end
  request.device.normals_offset = need;
  EXPECT_EQ(CheckDeviceRequest(request, *mesh, 1, opencl).code(), StatusCode::kInvalidArgument);
  request.device.normals = false;
  s = CheckDeviceRequest(request, *mesh, 2, BackendInfo{.id = "simd"});
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("imported by backend 'opencl', not by 'simd'"), std::string::npos)
      << s.message();
  std::vector<float> host(3000);
  request.positions = host;  // host and device outputs at once
  EXPECT_EQ(CheckDeviceRequest(request, *mesh, 1, opencl).code(), StatusCode::kInvalidArgument);
}

TEST(DeviceRequestCheckTest, EncodingsTheBackendWritesInTheirOwnSizes) {
  auto mesh = TestMesh(1000);
  const uint64_t half = 6000;  // float16 and snorm16: 2 bytes a value
  FakeMemory memory(2 * half + 64, "opencl");
  BackendInfo opencl{.id = "opencl",
                     .encoded_outputs = {VertexEncoding::kFloat16, VertexEncoding::kSnorm16}};
  Bounds boxes[2];
  SkinRequest request;
  request.instances = 2;
  request.device = {.memory = &memory,
                    .positions_offset = 64,
                    .instance_bytes = half,
                    .encoding = VertexEncoding::kFloat16};
  // Two float16 instances fit where two float32 ones would not.
  EXPECT_TRUE(CheckDeviceRequest(request, *mesh, 2, opencl).ok());
  request.device.positions_offset = 66;
  EXPECT_EQ(CheckDeviceRequest(request, *mesh, 2, opencl).code(), StatusCode::kInvalidArgument);
  request.device.positions_offset = 64;
  request.device.encoding = VertexEncoding::kSnorm16;  // needs somewhere for the boxes
  Status s = CheckDeviceRequest(request, *mesh, 2, opencl);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("device.bounds is null; snorm16"), std::string::npos) << s.message();
  request.device.bounds = boxes;
  EXPECT_TRUE(CheckDeviceRequest(request, *mesh, 2, opencl).ok());
  EXPECT_EQ(InstanceDeviceOutput(request, 1).bounds, &boxes[1]);
  // A backend that does not write the encoding itself cannot: nothing is read back.
  s = CheckDeviceRequest(request, *mesh, 2, BackendInfo{.id = "opencl"});
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("does not write snorm16 itself"), std::string::npos) << s.message();
}

// Through the engine: a frame with device output passes its checks and reaches the
// backend's device path (memory not of OpenCL's making stops it there, named), and a range
// past the memory is refused before any backend runs.
TEST(EngineDeviceOutputTest, ReachesTheBackendsDevicePath) {
  EngineOptions options;
  options.enabled_backends = {"opencl"};
  options.compute_threads = 1;
  auto engine = Engine::Create(options);
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  auto mesh = (*engine)->AddMesh(MakeSyntheticMesh({.vertex_count = 1000, .normals = true}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const uint64_t array = 12000;
  FakeMemory memory(4 * array, "opencl");
  std::vector<float> palette = MakeSyntheticPalette(77, 1, 0);
  const std::vector<float> second = MakeSyntheticPalette(77, 1, 1);
  palette.insert(palette.end(), second.begin(), second.end());
  SkinRequest request{.mesh_id = mesh->id, .backend = "opencl", .palette = palette, .instances = 2};
  request.device = {.memory = &memory,
                    .positions_offset = 0,
                    .normals_offset = 2 * array,
                    .instance_bytes = array,
                    .normals = true};
  Status s = (*engine)->SkinBlocking(request);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("not made by the opencl backend"), std::string::npos) << s.message();
  request.device.normals_offset = 2 * array + 64;  // the second instance's normals stick out
  s = (*engine)->SkinBlocking(request);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("instance 1's output"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace skinserve::testing
