#!/bin/bash
# Device call (from the repository root, build-gpu/ carried):
# binary (bench-copies), alternated rounds; one chunk (the kernel alone) and the default two;
# the paper's shuffled order, and sorted once; DQ rows too.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
nvidia-smi --query-gpu=name,memory.total,clocks.max.sm --format=csv > $OUT/machine.txt; lscpu | head -20 >> $OUT/machine.txt
rows='BM_(Skin|SkinNormals|SkinQuantized|SkinQuantizedWeights8|SkinDualQuaternion)/opencl/1600000/[14]/|BM_DeviceMemoryCopy'
common="--opencl-device=gpu --backends=opencl --vertices=1600000 --bones=1,4 --quantized --methods=linear,dual-quaternion --benchmark_repetitions=3 --benchmark_min_time=0.2"
run() {  # $1 name  $2 chunks  $3 copies  $4.. extra flags
  local name=$1 chunks=$2 copies=$3; shift 3
  echo "BENCH=${BENCH:-bench-copies} SKINSERVE_OPENCL_CHUNKS=$chunks SKINSERVE_OPENCL_PALETTE_COPIES=$copies bin/${BENCH:-bench-copies} $common --benchmark_filter='$rows' $*" >> $OUT/commands.txt
  SKINSERVE_OPENCL_CHUNKS=$chunks SKINSERVE_OPENCL_PALETTE_COPIES=$copies timeout 120 bin/${BENCH:-bench-copies} $common --benchmark_filter="$rows" "$@" \
    --benchmark_out=$OUT/$name.json --benchmark_out_format=json > $OUT/$name.txt 2>&1
  echo "$name rc=$? $(date +%T)"
}
date +%T
# Arguments: name:chunks:copies[:extra flag], run in order.
for spec in "$@"; do
  IFS=: read -r name chunks copies extra <<< "$spec"
  run $name $chunks $copies $extra
done
