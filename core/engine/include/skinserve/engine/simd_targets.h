// The `simd` backends' run-time SIMD targets (Google Highway): which ones this binary and
// CPU can run, and a backend capped at one of them, so every target is testable on a
// machine that has a better one.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "skinserve/engine/backend.h"

namespace skinserve {

// Environment variable read by CreateAllBackends: the best target `simd` and
// `simd-openmp` may use, by Highway's name (e.g. AVX2). Unset: the best the CPU runs.
inline constexpr const char* kSimdMaxTargetVariable = "SKINSERVE_SIMD_MAX_TARGET";

// Targets compiled in that this CPU runs, best first, by Highway's names
// (x86: AVX3, AVX2, SSE4, EMU128; Arm: SVE2, SVE, NEON, EMU128...).
std::vector<std::string> RunnableSimdTargets();

// Caps, for the whole process, the run-time dispatch of the other Highway loops (the
// vertex encodings' snorm16 kernels) at `max_target` (empty: the CPU's best again), so
// tests cover each target; INVALID_ARGUMENT naming the runnable ones for an unknown target.
// Not meant for a serving process: call it while nothing else encodes.
Status CapSimdDispatch(const std::string& max_target);

// `simd` (threads <= 0: one thread, the caller's) or `simd-openmp` on `threads` threads (like
// `sse-openmp`, even when that is one) at the best runnable target no better than
// `max_target` (empty: the best). An unknown or unrunnable target gives an unavailable
// backend whose reason names the runnable ones.
std::unique_ptr<Backend> CreateSimdBackend(int threads, const std::string& max_target);

}  // namespace skinserve
