// The shared runtime's facts: both ids, available here, describing the device and PoCL,
// PoCL's thread count taken from the engine, cl* errors named; and PoCL running kernels
// on CL_MEM_USE_HOST_PTR memory in place, which is what makes `opencl-zerocopy` copy-free.
#include <gtest/gtest.h>

#include <cstdlib>
#include <limits>
#include <string>

#include "backends/opencl_runtime.h"
#include "opencl_test_support.h"
#include "skinserve/core/aligned_buffer.h"
#include "skinserve/core/synthetic.h"

namespace skinserve::testing {
namespace {

TEST(OpenClRuntimeTest, BothBackendsAreAvailableWithTheirIdsAndDevice) {
  const auto& backends = OpenClBackends();
  ASSERT_EQ(backends.size(), 2u);
  EXPECT_EQ(backends[0]->info().id, "opencl");
  EXPECT_EQ(backends[1]->info().id, "opencl-zerocopy");
  for (const auto& backend : backends) {
    const BackendInfo& info = backend->info();
    // This machine, CI and the container install PoCL: unavailable here is a failure.
    ASSERT_TRUE(info.available) << info.id << ": " << info.unavailable_reason;
    EXPECT_FALSE(info.device.empty()) << info.id;
    EXPECT_NE(info.description.find("PoCL"), std::string::npos) << info.description;
    EXPECT_GE(info.simd_width, 4) << info.id << ": a CPU device has at least SSE's 4 lanes";
    EXPECT_EQ(info.device, backends[0]->info().device) << "one shared device";
  }
}

TEST(OpenClRuntimeTest, PoclRunsTheEnginesThreadCount) {
  SKIP_IF_OPENCL_UNAVAILABLE(*OpenClBackends()[0]);
  if (PoclThreadsPresetByEnvironment()) {
    GTEST_SKIP() << "POCL_MAX_PTHREAD_COUNT was set before the test: the operator's choice wins";
  }
  const char* env = std::getenv("POCL_MAX_PTHREAD_COUNT");
  ASSERT_NE(env, nullptr) << "the runtime did not set POCL_MAX_PTHREAD_COUNT";
  EXPECT_EQ(std::string(env), std::to_string(kOpenClTestThreads));
  for (const auto& backend : OpenClBackends()) {
    EXPECT_EQ(backend->info().threads, kOpenClTestThreads) << backend->info().id;
  }
}

TEST(OpenClRuntimeTest, ClErrorsNameTheCallAndTheCode) {
  Status invalid = ClError("clCreateBuffer(palette)", CL_INVALID_VALUE);
  EXPECT_EQ(invalid.code(), StatusCode::kInternal);
  EXPECT_EQ(invalid.message(), "clCreateBuffer(palette) failed: CL_INVALID_VALUE (-30)");
  Status memory = ClError("clCreateBuffer(positions)", CL_MEM_OBJECT_ALLOCATION_FAILURE);
  EXPECT_EQ(memory.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(memory.message().find("CL_MEM_OBJECT_ALLOCATION_FAILURE (-4)"), std::string::npos);
  EXPECT_STREQ(ClErrorName(CL_BUILD_PROGRAM_FAILURE), "CL_BUILD_PROGRAM_FAILURE");
  EXPECT_STREQ(ClErrorName(CL_INVALID_KERNEL_ARGS), "CL_INVALID_KERNEL_ARGS");
  EXPECT_STREQ(ClErrorName(-1001), "CL_PLATFORM_NOT_FOUND_KHR");
  EXPECT_STREQ(ClErrorName(-9999), "CL_UNKNOWN_ERROR");
}

// The zero-copy backend's premise, checked on the runtime it uses: after the kernel and a
// clFinish, and before any map, the results are already in the host memory the output
// buffers wrap: PoCL ran the kernel on it. Aligned and one float off alignment.
TEST(OpenClRuntimeTest, PoclSkinsUseHostPtrBuffersInPlace) {
  SKIP_IF_OPENCL_UNAVAILABLE(*OpenClBackends()[0]);
  if (OpenClBackends()[0]->info().description.find("PoCL") == std::string::npos) {
    GTEST_SKIP() << "not PoCL: other devices may copy (and then the map copies back)";
  }
  auto runtime = OpenClRuntime::Create(kOpenClTestThreads);  // the process's PoCL, again
  ASSERT_TRUE(runtime.ok()) << runtime.status().ToString();
  OpenClRuntime& cl = **runtime;
  constexpr uint32_t kVertices = 1001;
  auto mesh = SyntheticMesh(kVertices, 2, 77, false, 5);
  const auto palette = MakeSyntheticPalette(77, 5, 1);
  for (std::size_t offset : {0u, 1u}) {
    AlignedBuffer<float> storage(3 * kVertices + offset);
    const std::span<float> out(storage.data() + offset, 3 * kVertices);
    std::fill(out.begin(), out.end(), std::numeric_limits<float>::quiet_NaN());
    constexpr cl_mem_flags kWrap = CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR;
    auto pal = cl.CreateBuffer("palette", kWrap, palette.size() * sizeof(float), palette.data());
    auto joints =
        cl.CreateBuffer("joints", kWrap, mesh->joints().size_bytes(), mesh->joints().data());
    auto weights =
        cl.CreateBuffer("weights", kWrap, mesh->weights().size_bytes(), mesh->weights().data());
    auto positions = cl.CreateBuffer("positions", kWrap, mesh->positions().size_bytes(),
                                     mesh->positions().data());
    auto output = cl.CreateBuffer("output", CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                  out.size_bytes(), out.data());
    for (const auto* buffer : {&pal, &joints, &weights, &positions, &output}) {
      ASSERT_TRUE(buffer->ok()) << buffer->status().ToString();
    }
    {
      std::lock_guard lock(cl.mutex());
      ASSERT_TRUE(cl.EnqueueSkin(*mesh, {.palette = pal->get(),
                                         .joints = joints->get(),
                                         .weights = weights->get(),
                                         .positions = positions->get(),
                                         .out_positions = output->get()})
                      .ok());
      ASSERT_EQ(clFinish(cl.queue()), CL_SUCCESS);
    }
    EXPECT_EQ(ReferenceMismatch(*mesh, palette, out, {}), "")
        << "offset " << offset << " floats: the results are not in the wrapped host memory "
        << "before a map, so PoCL copied";
  }
}

}  // namespace
}  // namespace skinserve::testing
