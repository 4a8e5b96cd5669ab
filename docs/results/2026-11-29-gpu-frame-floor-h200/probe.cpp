// The floor of one GPU frame on NVIDIA's OpenCL: per-iteration wall time (median of 2000) of
// an in-order queue doing (a) clFinish alone, (b) a 3.7 KB palette write from pinned memory +
// clFinish, (c) a small kernel + clFinish, (d) write + kernel + clFinish (a frame's commands),
// (e) (d) waited with clWaitForEvents on the kernel's event instead of clFinish, (f) (d) with
// the kernel writing 100k x 12 bytes. Build: g++ -O2 probe.cpp -lOpenCL -o probe
#define CL_TARGET_OPENCL_VERSION 300
#include <CL/cl.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <vector>

#define CHECK(x)                                                    \
  do {                                                              \
    cl_int e_ = (x);                                                \
    if (e_ != CL_SUCCESS) {                                         \
      std::fprintf(stderr, "%s: %d (line %d)\n", #x, e_, __LINE__); \
      std::exit(1);                                                 \
    }                                                               \
  } while (0)

static const char* kSource = R"CL(
__kernel void touch(__global const float* palette, __global float* out, uint n) {
  uint i = get_global_id(0);
  if (i < n) out[i] = palette[i % 924] * 2.0f;
}
)CL";

static double MedianUs(const std::function<void()>& body) {
  std::vector<double> t;
  for (int i = 0; i < 200; ++i) body();  // warm-up
  for (int i = 0; i < 2000; ++i) {
    auto a = std::chrono::steady_clock::now();
    body();
    t.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - a).count());
  }
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  return t[t.size() / 2];
}

int main() {
  cl_platform_id platform;
  CHECK(clGetPlatformIDs(1, &platform, nullptr));
  cl_device_id device;
  CHECK(clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, 1, &device, nullptr));
  char name[256];
  CHECK(clGetDeviceInfo(device, CL_DEVICE_NAME, sizeof(name), name, nullptr));
  std::printf("device: %s\n", name);
  cl_int err;
  cl_context context = clCreateContext(nullptr, 1, &device, nullptr, nullptr, &err);
  CHECK(err);
  cl_command_queue queue = clCreateCommandQueueWithProperties(context, device, nullptr, &err);
  CHECK(err);
  cl_program program = clCreateProgramWithSource(context, 1, &kSource, nullptr, &err);
  CHECK(err);
  CHECK(clBuildProgram(program, 1, &device, "", nullptr, nullptr));
  cl_kernel kernel = clCreateKernel(program, "touch", &err);
  CHECK(err);
  const size_t palette_bytes = 77 * 48, big = 300000;  // 100k x 3 floats
  cl_mem palette = clCreateBuffer(context, CL_MEM_READ_ONLY, palette_bytes, nullptr, &err);
  CHECK(err);
  cl_mem out = clCreateBuffer(context, CL_MEM_READ_WRITE, big * sizeof(float), nullptr, &err);
  CHECK(err);
  cl_mem pinned = clCreateBuffer(context, CL_MEM_ALLOC_HOST_PTR, palette_bytes, nullptr, &err);
  CHECK(err);
  void* host = clEnqueueMapBuffer(queue, pinned, CL_TRUE, CL_MAP_WRITE, 0, palette_bytes, 0,
                                  nullptr, nullptr, &err);
  CHECK(err);
  CHECK(clSetKernelArg(kernel, 0, sizeof(cl_mem), &palette));
  CHECK(clSetKernelArg(kernel, 1, sizeof(cl_mem), &out));
  auto run = [&](cl_uint n, bool write, bool kernel_on, bool wait_event) {
    if (write)
      CHECK(clEnqueueWriteBuffer(queue, palette, CL_FALSE, 0, palette_bytes, host, 0, nullptr,
                                 nullptr));
    cl_event done = nullptr;
    if (kernel_on) {
      CHECK(clSetKernelArg(kernel, 2, sizeof(cl_uint), &n));
      const size_t global = (n + 255) / 256 * 256, local = 256;
      CHECK(clEnqueueNDRangeKernel(queue, kernel, 1, nullptr, &global, &local, 0, nullptr,
                                   wait_event ? &done : nullptr));
    }
    if (wait_event && done) {
      CHECK(clFlush(queue));
      CHECK(clWaitForEvents(1, &done));
      CHECK(clReleaseEvent(done));
    } else {
      CHECK(clFinish(queue));
    }
  };
  std::printf("a finish alone: %.1f us\n", MedianUs([&] { run(0, false, false, false); }));
  std::printf("b palette write + finish: %.1f us\n", MedianUs([&] { run(0, true, false, false); }));
  std::printf("c small kernel + finish: %.1f us\n",
              MedianUs([&] { run(1024, false, true, false); }));
  std::printf("d write + small kernel + finish: %.1f us\n",
              MedianUs([&] { run(1024, true, true, false); }));
  std::printf("e write + small kernel, wait on its event: %.1f us\n",
              MedianUs([&] { run(1024, true, true, true); }));
  std::printf("f write + kernel over 300k floats + finish: %.1f us\n",
              MedianUs([&] { run(300000, true, true, false); }));
  return 0;
}
