// The Highway targets of the `simd` loops, included before <hwy/foreach_target.h> by both
// kernels: simd_kernel.cpp calls into simd_dual_quaternion_kernel.cpp per target, so they
// must list the same ones. SSSE3 would add compile time and nothing over SSE4 on any CPU we
// run on; sanitizer builds take AVX2 and the fallback alone (core/engine/CMakeLists.txt).
#pragma once

// No Highway header before this: detect_targets.h would define HWY_DISABLED_TARGETS first.

#ifndef HWY_DISABLED_TARGETS
#ifdef SKINSERVE_SIMD_SANITIZER_TARGETS
#define HWY_DISABLED_TARGETS (HWY_SSSE3 | HWY_SSE4 | HWY_AVX3 | HWY_AVX3_DL)
#else
#define HWY_DISABLED_TARGETS HWY_SSSE3
#endif
#endif
