#include "skinserve/animation/pose_isa.h"

#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "isa_clones.h"

namespace skinserve::animation {
namespace {

// BestPoseIsa(), or what SKINSERVE_POSE_ISA asks for. A value it does not know, or an ISA
// this CPU lacks, is said on stderr (the process goes on with the best it has).
PoseIsa InitialIsa() {
  const PoseIsa best = BestPoseIsa();
  const char* asked = std::getenv("SKINSERVE_POSE_ISA");
  if (asked == nullptr || *asked == '\0') return best;
  for (PoseIsa isa : {PoseIsa::kBaseline, PoseIsa::kAvx2Fma}) {
    if (std::strcmp(asked, PoseIsaName(isa)) != 0) continue;
    if (isa == PoseIsa::kAvx2Fma && best != PoseIsa::kAvx2Fma) break;
    return isa;
  }
  std::fprintf(stderr,
               "skinserve: SKINSERVE_POSE_ISA=%s is not an ISA this CPU runs (baseline%s); the "
               "pose jobs run %s\n",
               asked, best == PoseIsa::kAvx2Fma ? ", avx2-fma" : "", PoseIsaName(best));
  return best;
}

std::atomic<PoseIsa>& Active() {
  static std::atomic<PoseIsa> active{InitialIsa()};
  return active;
}

}  // namespace

const char* PoseIsaName(PoseIsa isa) { return isa == PoseIsa::kAvx2Fma ? "avx2-fma" : "baseline"; }

PoseIsa BestPoseIsa() {
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return PoseIsa::kAvx2Fma;
#endif
  return PoseIsa::kBaseline;
}

PoseIsa ActivePoseIsa() { return Active().load(std::memory_order_relaxed); }

Status SetPoseIsa(PoseIsa isa) {
  if (isa == PoseIsa::kAvx2Fma && BestPoseIsa() != PoseIsa::kAvx2Fma) {
    return FailedPrecondition(
        fmt::format("pose ISA {}: this CPU lacks AVX2 or FMA", PoseIsaName(isa)));
  }
  Active().store(isa, std::memory_order_relaxed);
  return Status::Ok();
}

namespace detail {
bool RunAvx2Fma() { return ActivePoseIsa() == PoseIsa::kAvx2Fma; }
}  // namespace detail

}  // namespace skinserve::animation
