// SKINSERVE_FORCE_INLINE: for the small helpers of the SIMD kernels (blend, transform, pack).
// GCC's inliner gives up on them once the block walk takes the kernel as a lambda, and a
// helper called out of line returns its registers through memory: the `sse` loop ran 4-5x
// slower that way (Blend<4> returning its four columns on the stack, 2026-11-24).
#pragma once

#define SKINSERVE_FORCE_INLINE inline __attribute__((always_inline))
