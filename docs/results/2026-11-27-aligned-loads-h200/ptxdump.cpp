// Builds OpenCL C sources for the first GPU and prints the program binary (PTX on NVIDIA).
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
int main(int argc, char** argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: ptxdump OPTIONS FILE...\n");
    return 2;
  }
  std::string src;
  for (int i = 2; i < argc; ++i) {
    std::ifstream f(argv[i]);
    std::stringstream s;
    s << f.rdbuf();
    src += s.str() + "\n";
  }
  cl_platform_id p;
  cl_device_id d;
  cl_int e;
  clGetPlatformIDs(1, &p, nullptr);
  if (clGetDeviceIDs(p, CL_DEVICE_TYPE_GPU, 1, &d, nullptr) != CL_SUCCESS) {
    fprintf(stderr, "no gpu\n");
    return 1;
  }
  cl_context c = clCreateContext(nullptr, 1, &d, nullptr, nullptr, &e);
  const char* s = src.c_str();
  cl_program prog = clCreateProgramWithSource(c, 1, &s, nullptr, &e);
  e = clBuildProgram(prog, 1, &d, argv[1], nullptr, nullptr);
  size_t n = 0;
  clGetProgramBuildInfo(prog, d, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
  std::vector<char> log(n + 1);
  clGetProgramBuildInfo(prog, d, CL_PROGRAM_BUILD_LOG, n, log.data(), nullptr);
  fprintf(stderr, "build %d\n%s\n", e, log.data());
  if (e != CL_SUCCESS) return 1;
  size_t size = 0;
  clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof(size), &size, nullptr);
  std::vector<unsigned char> bin(size);
  unsigned char* ptr = bin.data();
  clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof(ptr), &ptr, nullptr);
  fwrite(bin.data(), 1, size, stdout);
}
