#!/bin/bash
# Device call 3 (16 Xeon cores; the GPU idle): issue 29's CPU rows.
#  a) the quantized simd loop: bench-3b02344 (chunk decode) against bench-main (positions and
#     normals converted in registers), alternated 3 rounds, simd-openmp 16 threads and simd on
#     one core, 1.6M x 4, float and quantized rows interleaved in each process;
#  b) simd / simd-openmp writing float16 / snorm16 themselves (BM_Skin*Encoded*) against float32
#     then the host encoder (BM_Skin*HostEncoded*), bench-main, 25k and 1.6M x 4.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
cd build-gpu
lscpu > $OUT/lscpu.txt; date +%T
for rep in 1 2 3; do
for b in 3b02344 main; do
  echo "bin/bench-$b --backends=simd-openmp --vertices=1600000 --bones=4 --quantized --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=5 --benchmark_enable_random_interleaving=true --benchmark_min_time=0.3" >> $OUT/commands.txt
  timeout 90 bin/bench-$b --backends=simd-openmp --vertices=1600000 --bones=4 --quantized \
    --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/|BM_MemoryBandwidth' --benchmark_repetitions=5 \
    --benchmark_enable_random_interleaving=true --benchmark_min_time=0.3 \
    --benchmark_out=$OUT/q16-$b-$rep.json --benchmark_out_format=json > $OUT/q16-$b-$rep.txt 2>&1
  timeout 90 taskset -c 2 bin/bench-$b --backends=simd --vertices=1600000 --bones=4 --quantized \
    --benchmark_filter='BM_Skin(Quantized|QuantizedWeights8)?/' --benchmark_repetitions=5 \
    --benchmark_enable_random_interleaving=true --benchmark_min_time=0.3 \
    --benchmark_out=$OUT/q1-$b-$rep.json --benchmark_out_format=json > $OUT/q1-$b-$rep.txt 2>&1
  echo "q $b $rep $(date +%T)"
done
done
echo "bin/bench-main --backends=simd,simd-openmp --vertices=25000,1600000 --bones=4 --encoding=float16,snorm16 --process-cpu-time --benchmark_filter='(HostEncoded|Encoded)' --benchmark_repetitions=7 --benchmark_enable_random_interleaving=true --benchmark_min_time=0.2" >> $OUT/commands.txt
timeout 200 bin/bench-main --backends=simd,simd-openmp --vertices=25000,1600000 --bones=4 --encoding=float16,snorm16 --process-cpu-time \
  --benchmark_filter='(HostEncoded|Encoded)' --benchmark_repetitions=7 --benchmark_enable_random_interleaving=true \
  --benchmark_min_time=0.2 --benchmark_out=$OUT/encoded.json --benchmark_out_format=json > $OUT/encoded.txt 2>&1
echo "encoded rc=$? $(date +%T)"
cd $OUT && tar czf all.tgz *.json *.txt && rm -f *.json
