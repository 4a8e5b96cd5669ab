// Splits a frame's vertices into one contiguous range per OpenMP thread: the paper's
// OpenMP scheme (static partition; threads share no output cache line but at the seams).
#pragma once

#include <algorithm>
#include <cstddef>

namespace skinserve {

// The threads one frame runs on: the scheduler's SkinFrame::threads, at most the
// backend's own `threads`; all of them when the frame asks for none (0).
inline int FrameThreads(int requested, int backend_threads) {
  return requested > 0 ? std::min(requested, backend_threads) : backend_threads;
}

// Calls skin_range(first, last) on `threads` OpenMP threads covering [0, count).
template <typename SkinRange>
void ParallelOverVertices(std::size_t count, int threads, const SkinRange& skin_range) {
  // Ranges start on multiples of 16 vertices, so a kernel that works on blocks of 4
  // vertices only meets a partial block at the very end.
  const std::size_t parts = static_cast<std::size_t>(threads);
  const std::size_t step = ((count + parts - 1) / parts + 15) / 16 * 16;
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int part = 0; part < threads; ++part) {
    const std::size_t first = std::min(count, static_cast<std::size_t>(part) * step);
    const std::size_t last = std::min(count, first + step);
    if (first < last) skin_range(first, last);
  }
}

}  // namespace skinserve
