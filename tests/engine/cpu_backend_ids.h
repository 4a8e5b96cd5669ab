// The paper's SSE backends are x86 only (listed unavailable elsewhere): core tests that
// need a SIMD backend name it through these, so the same tests run on arm64 (under qemu).
#pragma once

namespace skinserve {

#if defined(__SSE2__)
inline constexpr char kSimdTestBackend[] = "sse";
inline constexpr char kSimdOpenMpTestBackend[] = "sse-openmp";
inline constexpr char kDualQuaternionOpenMpTestBackend[] = "sse-openmp";  // threads + DQS
#else
inline constexpr char kSimdTestBackend[] = "simd";
inline constexpr char kSimdOpenMpTestBackend[] = "simd-openmp";
inline constexpr char kDualQuaternionOpenMpTestBackend[] = "openmp";
#endif

}  // namespace skinserve
