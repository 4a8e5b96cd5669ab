// Splits a frame's vertices into one contiguous range per OpenMP thread: the paper's
// OpenMP scheme (static partition, no sharing of output cache lines but at the seams).
#pragma once

#include <omp.h>

#include <algorithm>
#include <cstddef>

namespace skinserve {

// Calls skin_range(first, last) on `threads` OpenMP threads covering [0, count).
template <typename SkinRange>
void ParallelOverVertices(std::size_t count, int threads, const SkinRange& skin_range) {
#pragma omp parallel num_threads(threads)
  {
    const std::size_t parts = static_cast<std::size_t>(omp_get_num_threads());
    const std::size_t part = static_cast<std::size_t>(omp_get_thread_num());
    // Ranges start on multiples of 16 vertices so SIMD backends rarely hit a remainder.
    const std::size_t step = (count + parts - 1) / parts;
    const std::size_t aligned_step = (step + 15) / 16 * 16;
    const std::size_t first = std::min(count, part * aligned_step);
    const std::size_t last = std::min(count, first + aligned_step);
    if (first < last) skin_range(first, last);
  }
}

}  // namespace skinserve
