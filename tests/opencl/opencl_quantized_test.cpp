// The quantized rest stream on the OpenCL runtimes the registry does not make: the GPU's
// path on PoCL ("opencl-staging": pinned staging in chunks; "opencl-coalesced": coalesced
// order, the palette in local memory up to 77 joints, the global kernels past it), against
// the float64 references on the dequantized and on the original input
// (tests/backends/quantized_reference.h). `opencl` and `opencl-zerocopy` on the CPU path:
// tests/backends/quantized_rest_test.cpp. Tangents against the reference on the decoded
// input. Representative cases only: PoCL compiles each kernel on its first launch on each
// runtime (seconds on the loaded 2-core machine).
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "backends/opencl/opencl_quantized.h"
#include "opencl_test_support.h"
#include "quantized_reference.h"
#include "reference_cases.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

TEST(OpenClQuantizedTest, StagedAndCoalescedRuntimesMatchBothReferences) {
  // 3000 vertices: three chunks of 1024 on the staged runtimes, not a multiple of a group.
  const QuantizedCase cases[] = {
      {3000, 4, 20, true, RestEncoding::kQuantized16},         // local palette, 8-bit joints
      {1001, 3, 77, false, RestEncoding::kQuantized8Weights},  // local palette at its limit
      {3000, 8, 300, true, RestEncoding::kQuantized8Weights},  // global kernels, 16-bit joints
      {5, 1, 300, true, RestEncoding::kQuantized16},           // one influence, a partial item
  };
  uint64_t seed = 900;
  for (const char* id : {"opencl-staging", "opencl-coalesced"}) {
    Backend& backend = OpenClBackend(id);
    SKIP_IF_OPENCL_UNAVAILABLE(backend);
    for (const QuantizedCase& c : cases) {
      const MeshArrays original = RandomQuantizedCaseMesh(c, ++seed);
      auto mesh = Mesh::Create(original, {.rest_encoding = c.encoding});
      ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
      auto prepared = backend.Prepare(*mesh);
      ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
      const auto palette = MakeSyntheticPalette(c.joints, seed, 2);
      constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
      std::vector<float> positions(3 * c.vertices, kNaN),
          normals(c.normals ? 3 * c.vertices : 0, kNaN);
      const Status s = backend.Skin(
          **prepared, {.palette = palette, .positions = positions, .normals = normals});
      ASSERT_TRUE(s.ok()) << id << ": " << s.ToString();
      const QuantizedErrors e = CheckQuantized(**mesh, original, palette, positions, normals);
      const std::string what = std::string(id) + " " + std::string(RestEncodingName(c.encoding)) +
                               " V=" + std::to_string(c.vertices) +
                               " B=" + std::to_string(c.influences) +
                               " J=" + std::to_string(c.joints);
      EXPECT_LE(e.dequantized_position, FloatTolerance(palette, original)) << what;
      EXPECT_LE(e.dequantized_normal, 1e-5) << what;
      EXPECT_LE(e.over_bound, 1.0) << what << ": error / stated bound on the original input";
    }
  }
}

// The stream's tangents on the same runtimes (qskin_tangents_* and, on the coalesced one,
// qskin_tangents_local_*): every output against the float64 reference on the decoded input
// (tangents' xyz 1e-5, w exact).
TEST(OpenClQuantizedTest, StagedAndCoalescedRuntimesSkinTheStreamsTangents) {
  const MeshCase cases[] = {
      {3000, 4, 20, true, true},   // local palette, 8-bit joints, three staged chunks
      {3000, 8, 300, true, true},  // global kernels, 16-bit joints
      {5, 1, 77, true, true},      // one influence, a partial item
  };
  uint64_t seed = 950;
  for (const char* id : {"opencl-staging", "opencl-coalesced"}) {
    Backend& backend = OpenClBackend(id);
    SKIP_IF_OPENCL_UNAVAILABLE(backend);
    for (const MeshCase& c : cases) {
      for (RestEncoding encoding : {RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
        ExpectQuantizedTangentsMatchReference(backend, c, encoding, ++seed, id);
      }
    }
  }
}

// The point of the stream on the device: a quantized mesh's buffers hold its integers only,
// 6 + B + 2 (B - 1) + 6 bytes a vertex at 8-bit joints, unorm16 weights and normals (B = 4:
// 24, against 12 + 8 + 16 + 12 = 48 as floats), and (B - 1) bytes of weights with unorm8.
TEST(OpenClQuantizedTest, TheDeviceHoldsOnlyTheIntegers) {
  auto runtime = CoalescedTestRuntime();
  if (!runtime.ok()) GTEST_SKIP() << runtime.status().ToString();
  auto size_of = [](const ClBuffer& buffer) {
    std::size_t bytes = 0;
    EXPECT_EQ(clGetMemObjectInfo(buffer.get(), CL_MEM_SIZE, sizeof(bytes), &bytes, nullptr),
              CL_SUCCESS);
    return bytes;
  };
  constexpr uint32_t kVertices = 1001;
  for (auto [encoding, weight_bytes, joints] :
       {std::tuple{RestEncoding::kQuantized16, 2u, 77u},
        std::tuple{RestEncoding::kQuantized8Weights, 1u, 300u}}) {
    const QuantizedCase c{kVertices, 4, joints, true, encoding};
    auto mesh = Mesh::Create(RandomQuantizedCaseMesh(c, 3), {.rest_encoding = encoding});
    ASSERT_TRUE(mesh.ok());
    auto device = CreateQuantizedDeviceMesh(**runtime, **mesh, CL_MEM_COPY_HOST_PTR);
    ASSERT_TRUE(device.ok()) << device.status().ToString();
    const std::size_t joint_bytes = joints <= 256 ? 1 : 2;
    EXPECT_EQ(size_of(device->positions), 6u * kVertices);
    EXPECT_EQ(size_of(device->normals), 6u * kVertices);
    EXPECT_EQ(size_of(device->joints), 4 * joint_bytes * kVertices);
    EXPECT_EQ(size_of(device->weights), 3 * weight_bytes * kVertices);
    EXPECT_EQ(device->tangents.get(), nullptr) << "the mesh has no tangents";
  }
  // With tangents: 4 snorm16 a vertex more.
  auto tangents = Mesh::Create(
      MakeSyntheticMesh({.vertex_count = kVertices, .normals = true, .tangents = true, .seed = 4}),
      {.rest_encoding = RestEncoding::kQuantized16});
  ASSERT_TRUE(tangents.ok());
  auto device = CreateQuantizedDeviceMesh(**runtime, **tangents, CL_MEM_COPY_HOST_PTR);
  ASSERT_TRUE(device.ok()) << device.status().ToString();
  EXPECT_EQ(size_of(device->tangents), 8u * kVertices);
}

}  // namespace
}  // namespace skinserve::testing
