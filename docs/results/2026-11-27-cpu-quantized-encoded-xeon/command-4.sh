#!/bin/bash
# Device call 4 (16 Xeon cores): quantized against float simd-openmp past the 300 MiB L3:
# 10M vertices x 4 (float stream 400 MB a frame), rows interleaved, memory bandwidth beside.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
cd build-gpu; date +%T
echo "bin/bench-main --backends=simd-openmp --vertices=10000000 --bones=4 --quantized --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=5 --benchmark_enable_random_interleaving=true --benchmark_min_time=0.5" > $OUT/commands.txt
timeout 400 bin/bench-main --backends=simd-openmp --vertices=10000000 --bones=4 --quantized \
  --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=5 \
  --benchmark_enable_random_interleaving=true --benchmark_min_time=0.5 \
  --benchmark_out=$OUT/q16-10m.json --benchmark_out_format=json > $OUT/q16-10m.txt 2>&1
echo "rc=$? $(date +%T)"
