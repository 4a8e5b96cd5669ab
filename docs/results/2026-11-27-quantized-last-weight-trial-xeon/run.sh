#!/bin/bash
# Device call: the quantized simd loop blending with its last weight decoded apart
# (bench-last) against main's differences (bench-old); 16 Xeon threads, alternated rounds.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
set -f  # the filter is a regex, not a glob
cd build-gpu; date +%T
lscpu > $OUT/machine.txt
for round in 1 2 3; do
  for bin in old last; do
    name=$bin-$round
    cmd="bin/bench-$bin --backends=simd-openmp,simd --vertices=1600000,10000000 --bones=4 --quantized --benchmark_filter=BM_Skin(Quantized|QuantizedWeights8)?/simd(-openmp)?/(1600000|10000000)/|BM_MemoryBandwidth --benchmark_repetitions=5 --benchmark_min_time=0.3"
    echo "$cmd" >> $OUT/commands.txt
    timeout 250 $cmd --benchmark_out=$OUT/$name.json --benchmark_out_format=json > $OUT/$name.txt 2>&1
    echo "$name rc=$? $(date +%T)"
  done
done
cd $OUT && tar czf all.tgz *.json *.txt && rm -f *.json *.txt
