#!/bin/bash
# Encoded output before (6c60a05: one memcpy out of pinned memory) and after (ParallelCopy),
# alternated, one device call.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
for rep in 1 2; do
for b in now fix; do
  timeout 150 bin/bench-$b --opencl-device=gpu --backends=opencl --vertices=1600000 --bones=4 --quantized \
    --encoding=snorm16,float16 --streams=4 --benchmark_repetitions=3 --benchmark_min_time=0.2 \
    --benchmark_filter='BM_Skin(Streams)?(Encoded(Snorm16|Float16))?/|BM_SkinQuantized/|BM_DeviceMemoryCopy|BM_PcieDeviceToHost' \
    --benchmark_out=$OUT/encoded-$b-$rep.json --benchmark_out_format=json > $OUT/encoded-$b-$rep.txt 2>&1
done
done
cd $OUT && tar czf all3.tgz * && rm -f *.json
