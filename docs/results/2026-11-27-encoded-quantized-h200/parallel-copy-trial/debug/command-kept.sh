#!/bin/bash
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
for rep in 1 2 3 4 5 6; do
LD_PRELOAD=$PWD/lib/libthrowhook.so timeout 200 bin/bench-kept --opencl-device=gpu --backends=opencl --vertices=1600000 --bones=4 --quantized \
    --encoding=snorm16,float16 --streams=4 --benchmark_repetitions=3 --benchmark_min_time=0.2 \
    --benchmark_filter='BM_Skin(Streams)?(Encoded(Snorm16|Float16))?/|BM_SkinQuantized/|BM_DeviceMemoryCopy|BM_PcieDeviceToHost' > $OUT/kept-$rep.txt 2>&1; echo "rc=$?" >> $OUT/kept-$rep.txt
done
grep -H "rc=\|bad_alloc" $OUT/*.txt
