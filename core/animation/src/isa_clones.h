// How a pose job's inner loop is compiled twice (see skinserve/animation/pose_isa.h): its
// body is an always-inlined function, called from a baseline function and from one
// compiled for AVX2 + FMA (`SKINSERVE_AVX2_FMA`); everything the body calls is inlined
// into each, so each clone is code for its own instructions. The library is compiled with
// -ffp-contract=fast: a * b + c becomes one FMA in the AVX2 clone (the baseline has none).
#pragma once

#include <atomic>

#include "skinserve/animation/pose_isa.h"

#if defined(__GNUC__)
#define SKINSERVE_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define SKINSERVE_ALWAYS_INLINE inline
#endif

#if defined(__x86_64__) && defined(__GNUC__)
#define SKINSERVE_HAS_AVX2_FMA_CLONES 1
#define SKINSERVE_AVX2_FMA __attribute__((target("avx2,fma")))
#else
#define SKINSERVE_HAS_AVX2_FMA_CLONES 0
#define SKINSERVE_AVX2_FMA
#endif

namespace skinserve::animation::detail {

// True when the jobs run their AVX2 + FMA clones (ActivePoseIsa(), cheap: one load).
bool RunAvx2Fma();

}  // namespace skinserve::animation::detail
