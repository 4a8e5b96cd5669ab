// The snorm16 hot loops of vertex_encoding.cpp, written once with Google Highway and
// dispatched at run time to the best target the CPU runs (AVX-512, AVX2, SSE4, NEON...).
// They only compute and report whether every value passed its check; the caller validates
// the arguments beforehand and finds and names a failing value afterwards. Values are x y z
// triples: `n` is a multiple of 3. The int16 pointers need no alignment (wire bytes).
#pragma once

#include <cstddef>
#include <cstdint>

namespace skinserve::encoding_kernels {

// Per axis min and max of n >= 3 values into lo[3] and hi[3]; false when some value is not
// finite (lo and hi are then meaningless).
bool Bounds(const float* in, std::size_t n, float* lo, float* hi);

// q = round_to_nearest_even(clamp((x - centre) * scale, +-32767)) per axis; false when some
// value lies outside [lo, hi] of its axis or is NaN (out then holds garbage).
bool EncodeSnorm16Positions(const float* in, std::size_t n, const float* centre, const float* scale,
                            const float* lo, const float* hi, void* out);

// x = centre + (q / 32767) * half_extent per axis.
void DecodeSnorm16Positions(const void* in, std::size_t n, const float* centre,
                            const float* half_extent, float* out);

// q = round_to_nearest_even(n * 32767); false when some |n * 32767| is not below 32767.5
// (a component outside [-1, 1] beyond rounding, or not finite).
bool EncodeSnorm16Normals(const float* in, std::size_t n, void* out);

// n = q / 32767.
void DecodeSnorm16Normals(const void* in, std::size_t n, float* out);

}  // namespace skinserve::encoding_kernels
