// What every tick row (BM_SkinTick*, skin_benchmark.cpp and device_output_benchmark.cpp)
// reports: vertices as items, and seconds_per_character over the run.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdint>

namespace skinserve::bench {

inline void SetTickCounters(benchmark::State& state, uint32_t characters, uint32_t vertices) {
  const double skinned = static_cast<double>(state.iterations()) * characters;
  state.SetItemsProcessed(static_cast<int64_t>(skinned * vertices));
  state.counters["seconds_per_character"] =
      benchmark::Counter(skinned, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

}  // namespace skinserve::bench
