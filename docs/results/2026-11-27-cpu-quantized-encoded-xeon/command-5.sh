#!/bin/bash
# Device call 5: run4's 10M x 4 rows twice more, 7 interleaved repetitions each.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
cd build-gpu; date +%T
for rep in 2 3; do
echo "bin/bench-main --backends=simd-openmp --vertices=10000000 --bones=4 --quantized --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=7 --benchmark_enable_random_interleaving=true --benchmark_min_time=0.5" >> $OUT/commands.txt
timeout 200 bin/bench-main --backends=simd-openmp --vertices=10000000 --bones=4 --quantized \
  --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=7 \
  --benchmark_enable_random_interleaving=true --benchmark_min_time=0.5 \
  --benchmark_out=$OUT/q16-10m-$rep.json --benchmark_out_format=json > $OUT/q16-10m-$rep.txt 2>&1
echo "rc=$? $(date +%T)"; tail -4 $OUT/q16-10m-$rep.txt
done
