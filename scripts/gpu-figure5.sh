#!/usr/bin/env bash
# Figure 5 today, on a machine with an OpenCL GPU: the CPU backends on every core (the
# paper's `sse-openmp` and today's fastest CPU loops, `simd` and `simd-openmp`) against
# the OpenCL backends on the GPU (transfers included, and kernel only), over the paper's
# grid, with the device's PCIe and memory bounds measured in the same run; then the
# OpenCL test suite on the GPU. Run from a folder holding bin/ (skinserve-bench,
# skinserve_opencl_tests) and lib/ (their shared libraries); results go to $1.
#   scripts/gpu-figure5.sh OUT [extra skinserve-bench flags]
# (e.g. --opencl-global-palette: `opencl` also with the palette read from global memory,
# rows opencl-global, beside the default local-memory palette; --device-output: `opencl`
# with its output left on the GPU, as GPU regions leave it, rows BM_SkinDeviceOutput through
# the device copy and BM_SkinDeviceOutputInPlace written in place.)
# Then, where gnuplot is: scripts/figure5-plot.sh OUT/figure5.json OUT/figure5.png (keep both in docs/results/<date>-<name>/)
set -uo pipefail
out=${1:?usage: gpu-figure5.sh OUT_DIR [bench flags]}
shift
here=$(cd "$(dirname "$0")" && pwd)
dir=${SKINSERVE_GPU_DIR:-$PWD}
export LD_LIBRARY_PATH=$dir/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
device=${SKINSERVE_OPENCL_DEVICE:-gpu}
mkdir -p "$out"
{
  nvidia-smi --query-gpu=name,driver_version,pcie.link.gen.current,pcie.link.width.current \
    --format=csv 2>&1
  lscpu | grep -E 'Model name|^CPU\(s\)' 2>&1
} >"$out/machine.txt"
# The grid, positions only: CPU backends on every core, OpenCL on the GPU, each OpenCL
# point also with 4 threads at once (frames of 4 streams in flight on 4 lanes).
"$dir/bin/skinserve-bench" --paper-tables --opencl-device="$device" \
  --backends=serial,sse,sse-openmp,simd,simd-openmp,openmp,opencl,opencl-zerocopy --streams=4 \
  --benchmark_min_time=0.2 --benchmark_out="$out/figure5.json" --benchmark_out_format=json \
  "$@" 2>&1 | tee "$out/bench.txt"
# The OpenCL tests on the GPU.
SKINSERVE_OPENCL_DEVICE=$device "$dir/bin/skinserve_opencl_tests" --gtest_brief=1 2>&1 \
  | tee "$out/opencl-tests.txt"
echo "tests exit: ${PIPESTATUS[0]}" | tee -a "$out/opencl-tests.txt"
