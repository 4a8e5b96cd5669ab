#!/bin/bash
# Device call (2026-11-27 session 2): the quantized stream's tangents on the GPU - the OpenCL
# tests on the device, then kernel and frame times of float vs quantized frames with tangents
# (and normals) at 1.6M x 4, one chunk (kernel only) and the default chunks; then simd-openmp on
# the 16 Xeon cores, same rows.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv > $OUT/gpu.txt 2>&1
lscpu > $OUT/lscpu.txt
date +%T
SKINSERVE_OPENCL_DEVICE=gpu timeout 200 bin/skinserve_opencl_tests --gtest_filter='*Quantized*:*Tangent*' > $OUT/opencl-tests.txt 2>&1; echo "rc=$?" >> $OUT/opencl-tests.txt
tail -4 $OUT/opencl-tests.txt; date +%T
rows='BM_Skin(Normals|Tangents)(Quantized|QuantizedWeights8)?/opencl/1600000/4/|BM_DeviceMemoryCopy|BM_Pcie'
common="--opencl-device=gpu --backends=opencl --vertices=1600000 --bones=4 --quantized --tangents --benchmark_repetitions=5 --benchmark_min_time=0.2"
run() {  # $1 name  $2 chunks  $3.. extra
  local name=$1 chunks=$2; shift 2
  echo "SKINSERVE_OPENCL_CHUNKS=$chunks bin/bench-tan $common --benchmark_filter='$rows' $*" >> $OUT/commands.txt
  SKINSERVE_OPENCL_CHUNKS=$chunks timeout 170 bin/bench-tan $common --benchmark_filter="$rows" "$@" \
    --benchmark_out=$OUT/$name.json --benchmark_out_format=json > $OUT/$name.txt 2>&1
  echo "$name rc=$? $(date +%T)"
}
run gpu-c1 1
run gpu-default ""
crows='BM_Skin(Normals|Tangents)(Quantized|QuantizedWeights8)?/simd-openmp/1600000/4/|BM_MemoryBandwidth'
echo "bin/bench-tan --backends=simd-openmp --vertices=1600000 --bones=4 --quantized --tangents --benchmark_repetitions=5 --benchmark_min_time=0.2 --benchmark_filter='$crows'" >> $OUT/commands.txt
timeout 170 bin/bench-tan --backends=simd-openmp --vertices=1600000 --bones=4 --quantized --tangents --benchmark_repetitions=5 --benchmark_min_time=0.2 --benchmark_filter="$crows" \
  --benchmark_out=$OUT/xeon.json --benchmark_out_format=json > $OUT/xeon.txt 2>&1
echo "xeon rc=$? $(date +%T)"
cd $OUT && tar czf all.tgz *.json *.txt && rm -f *.json
