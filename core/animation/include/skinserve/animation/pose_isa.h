// Which instructions the pose jobs' inner loops run with. Each loop is compiled twice: for
// x86-64's baseline (SSE2, what every x86-64 CPU has, as ozz's SSE2 runtime) and for AVX2
// with FMA (three-operand forms, broadcasts from memory, fused multiply-adds). The jobs
// take the best this CPU runs, unless SKINSERVE_POSE_ISA=baseline in the environment (or
// SetPoseIsa) says otherwise: tests run both, benchmarks can compare them. Results differ
// by float rounding only (FMA rounds once); both stay within the jobs' error targets.
#pragma once

#include <cstdint>

#include "skinserve/model/status.h"

namespace skinserve::animation {

enum class PoseIsa : uint8_t {
  kBaseline,  // SSE2 on x86-64; plain C++ elsewhere
  kAvx2Fma,   // x86-64 CPUs with AVX2 and FMA
};

const char* PoseIsaName(PoseIsa isa);  // "baseline", "avx2-fma"

// The best this CPU runs.
PoseIsa BestPoseIsa();

// What the jobs run now: BestPoseIsa(), or what SKINSERVE_POSE_ISA ("baseline" or
// "avx2-fma", read once, at the first job) or SetPoseIsa chose.
PoseIsa ActivePoseIsa();

// For tests and benchmarks: every job from now on runs `isa` (process-wide; call it while
// no job runs). FAILED_PRECONDITION, naming the ISA, where this CPU lacks it.
Status SetPoseIsa(PoseIsa isa);

}  // namespace skinserve::animation
