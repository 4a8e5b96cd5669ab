// The shared runtime's facts: both ids, available here, describing the device and PoCL,
// PoCL's thread count taken from the engine, cl* errors named; and PoCL running kernels
// on CL_MEM_USE_HOST_PTR memory in place, which is what makes `opencl-zerocopy` copy-free.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "backends/common/backend_factories.h"
#include "backends/opencl/opencl_runtime.h"
#include "opencl_test_support.h"
#include "skinserve/engine/engine.h"
#include "skinserve/model/aligned_buffer.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

// Whether the tests run on PoCL (the default device here and in CI) rather than on a
// device chosen with SKINSERVE_OPENCL_DEVICE.
bool OnPocl() { return OpenClBackends()[0]->info().description.find("PoCL") != std::string::npos; }

TEST(OpenClRuntimeTest, BothBackendsAreAvailableWithTheirIdsAndDevice) {
  const auto& backends = OpenClBackends();
  ASSERT_EQ(backends.size(), 2u);
  EXPECT_EQ(backends[0]->info().id, "opencl");
  EXPECT_EQ(backends[1]->info().id, "opencl-zerocopy");
  for (const auto& backend : backends) {
    const BackendInfo& info = backend->info();
    // This machine, CI and the container install PoCL; on the GPU machine the chosen
    // device is there: unavailable is a failure.
    ASSERT_TRUE(info.available) << info.id << ": " << info.unavailable_reason;
    EXPECT_FALSE(info.device.empty()) << info.id;
    if (OpenClTestDevice().empty()) {
      EXPECT_NE(info.description.find("PoCL"), std::string::npos) << info.description;
      EXPECT_GE(info.simd_width, 4) << info.id << ": a CPU device has at least SSE's 4 lanes";
    }
    EXPECT_EQ(info.device, backends[0]->info().device) << "one shared device";
  }
}

TEST(OpenClRuntimeTest, DeviceChoiceMatchesTypeOrNameAndNamesWhatThereIsWhenNot) {
  SKIP_IF_OPENCL_UNAVAILABLE(*OpenClBackends()[0]);
  const std::string device = OpenClBackends()[0]->info().device;
  // Part of the device's name, in another case, finds it.
  std::string part = device.substr(0, std::min<std::size_t>(device.size(), 6));
  for (char& ch : part) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  auto by_name = OpenClRuntime::Create({.threads = kOpenClTestThreads, .device = part});
  ASSERT_TRUE(by_name.ok()) << by_name.status().ToString();
  EXPECT_EQ((*by_name)->device_name(), device);
  if (OnPocl()) {
    auto cpu = OpenClRuntime::Create({.threads = kOpenClTestThreads, .device = "cpu"});
    ASSERT_TRUE(cpu.ok()) << cpu.status().ToString();
    EXPECT_TRUE((*cpu)->is_cpu());
    EXPECT_FALSE((*cpu)->staging()) << "PoCL shares host memory: no staging";
  }
  auto none = OpenClRuntime::Create({.threads = kOpenClTestThreads, .device = "no-such-device"});
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(none.status().message().find("'no-such-device'"), std::string::npos)
      << none.status().message();
  EXPECT_NE(none.status().message().find("device '" + device + "'"), std::string::npos)
      << "the error lists the devices found: " << none.status().message();
  // The factory turns it into two unavailable backends carrying the same reason.
  auto backends = MakeOpenClBackends(kOpenClTestThreads, "no-such-device");
  ASSERT_EQ(backends.size(), 2u);
  for (const auto& backend : backends) {
    EXPECT_FALSE(backend->info().available);
    EXPECT_EQ(backend->info().unavailable_reason, none.status().message());
  }
}

// An engine (a server) told to use a device that is not there does not start.
TEST(OpenClRuntimeTest, AnEngineWithAnUnmatchedDeviceChoiceFailsToStart) {
  EngineOptions options;
  options.compute_threads = 1;
  options.opencl_device = "no-such-device";
  auto engine = Engine::Create(options);
  ASSERT_FALSE(engine.ok());
  EXPECT_EQ(engine.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(engine.status().message().find("'no-such-device'"), std::string::npos)
      << engine.status().message();
}

// With device timing (profiled queues, OpenClRuntimeOptions::device_timing) every frame
// reports its device time from the profiling events: some kernel time, and some transfer
// time (the palette goes in, the result comes out); without it (the default) 0, and the
// frame is the same.
TEST(OpenClRuntimeTest, FramesReportKernelAndTransferTimeWhenProfiled) {
  // {opencl, opencl-zerocopy} direct, then {opencl, opencl-zerocopy} on the staging path,
  // each beside the tests' unprofiled backend of the same path.
  static const auto* direct = new std::vector<std::unique_ptr<Backend>>(
      MakeOpenClBackends(kOpenClTestThreads, OpenClTestDevice(), false, /*device_timing=*/true));
  static const auto* staged = new std::vector<std::unique_ptr<Backend>>(
      MakeOpenClBackends(kOpenClTestThreads, OpenClTestDevice(), true, /*device_timing=*/true));
  const std::vector<std::pair<Backend*, Backend*>> pairs = {
      {(*direct)[0].get(), &OpenClBackend("opencl")},
      {(*direct)[1].get(), &OpenClBackend("opencl-zerocopy")},
      {(*staged)[0].get(), &OpenClBackend("opencl-staging")}};
  auto mesh = SyntheticMesh(70001, 3, 77, true, 11);
  const auto palette = MakeSyntheticPalette(77, 11, 0);
  for (const auto& [timed, plain] : pairs) {
    for (Backend* backend : {timed, plain}) {
      SKIP_IF_OPENCL_UNAVAILABLE(*backend);
      const bool expect_time = backend == timed;
      const std::string what = backend->info().id + (expect_time ? " profiled" : " default");
      auto prepared = backend->Prepare(mesh);
      ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
      std::vector<float> positions(3 * 70001), normals(3 * 70001);
      DeviceTiming timing;
      ASSERT_TRUE(backend
                      ->Skin(**prepared, {.palette = palette,
                                          .positions = positions,
                                          .normals = normals,
                                          .device_timing = &timing})
                      .ok())
          << what;
      EXPECT_EQ(timing.kernel_ns > 0, expect_time) << what << ": " << timing.kernel_ns;
      EXPECT_EQ(timing.transfer_ns > 0, expect_time) << what << ": " << timing.transfer_ns;
      EXPECT_EQ(ReferenceMismatch(*mesh, palette, positions, normals), "") << what;
    }
  }
}

// Which kernels a frame takes: the CPU path (PoCL's own runtime) never stages the palette;
// the coalesced runtime stages it exactly when its 12 (linear) or 8 (dual quaternion)
// floats per joint fit the limit, so the reference cases of "opencl-coalesced" (1, 77 and
// 1024 joints) run both the local and the global kernels.
TEST(OpenClRuntimeTest, LocalPaletteWhereTheCoalescedPathsPaletteFits) {
  SKIP_IF_OPENCL_UNAVAILABLE(*OpenClBackends()[0]);
  auto runtime = CoalescedTestRuntime();
  ASSERT_TRUE(runtime.ok()) << runtime.status().ToString();
  const OpenClRuntime& coalesced = **runtime;
  EXPECT_TRUE(coalesced.coalesced());
  ASSERT_TRUE(coalesced.local_palette());
  EXPECT_EQ(coalesced.local_palette_bytes(), kCoalescedLocalPaletteBytes);
  EXPECT_EQ(coalesced.local_tiles(), kCoalescedLocalTiles);
  EXPECT_NE(OpenClBackend("opencl-coalesced").info().description.find("staged in local memory"),
            std::string::npos);
  // 77 joints: 3696 bytes as matrices, the limit; 115 joints: 3680 as dual quaternions.
  auto joints = [](uint32_t j) { return SyntheticMesh(5, 2, j, false, j); };
  EXPECT_TRUE(coalesced.UsesLocalPalette(*joints(1), SkinningMethod::kLinear));
  EXPECT_TRUE(coalesced.UsesLocalPalette(*joints(77), SkinningMethod::kLinear));
  EXPECT_FALSE(coalesced.UsesLocalPalette(*joints(78), SkinningMethod::kLinear));
  EXPECT_TRUE(coalesced.UsesLocalPalette(*joints(115), SkinningMethod::kDualQuaternion));
  EXPECT_FALSE(coalesced.UsesLocalPalette(*joints(116), SkinningMethod::kDualQuaternion));
  EXPECT_FALSE(coalesced.UsesLocalPalette(*joints(1024), SkinningMethod::kLinear));
  if (OnPocl()) {
    EXPECT_EQ(OpenClBackends()[0]->info().description.find("local memory"), std::string::npos)
        << "PoCL's CPU path keeps reading the palette from global memory";
  }
}

TEST(OpenClRuntimeTest, PoclRunsTheEnginesThreadCount) {
  SKIP_IF_OPENCL_UNAVAILABLE(*OpenClBackends()[0]);
  if (!OnPocl()) GTEST_SKIP() << "not PoCL: " << OpenClBackends()[0]->info().description;
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
  if (!OnPocl()) {
    GTEST_SKIP() << "not PoCL: other devices may copy (and then the map copies back)";
  }
  // The process's PoCL, again.
  auto runtime = OpenClRuntime::Create({.threads = kOpenClTestThreads, .device = "cpu"});
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
      auto lane = cl.AcquireLane();
      ASSERT_TRUE(cl.EnqueueSkin(*lane, *mesh,
                                 {.palette = pal->get(),
                                  .joints = joints->get(),
                                  .weights = weights->get(),
                                  .positions = positions->get(),
                                  .out_positions = output->get()},
                                 0, kVertices, nullptr)
                      .ok());
      ASSERT_EQ(clFinish(lane->compute), CL_SUCCESS);
    }
    EXPECT_EQ(ReferenceMismatch(*mesh, palette, out, {}), "")
        << "offset " << offset << " floats: the results are not in the wrapped host memory "
        << "before a map, so PoCL copied";
  }
}

}  // namespace
}  // namespace skinserve::testing
