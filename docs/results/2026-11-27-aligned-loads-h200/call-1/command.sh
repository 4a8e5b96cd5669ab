#!/bin/bash
# Device call 1: the OpenCL kernel's share of the H200's copy bound, before/now (aligned vector
# loads of palette, joints, weights), chunks 2 (default) and 1, shuffled and sorted vertex order;
# then the PTX of both kernel sources.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv > $OUT/gpu.txt 2>&1
lscpu > $OUT/lscpu.txt
rows='BM_(Skin|SkinNormals|SkinQuantized)/opencl/1600000/[14]/|BM_DeviceMemoryCopy'
common="--opencl-device=gpu --backends=opencl --vertices=1600000 --bones=1,4 --quantized --benchmark_repetitions=3 --benchmark_min_time=0.2"
run() {  # $1 name  $2 binary  $3 chunks  $4.. extra flags
  local name=$1 bin=$2 chunks=$3; shift 3
  echo "SKINSERVE_OPENCL_CHUNKS=$chunks bin/$bin $common --benchmark_filter='$rows' $*" >> $OUT/commands.txt
  SKINSERVE_OPENCL_CHUNKS=$chunks timeout 150 bin/$bin $common --benchmark_filter="$rows" "$@" \
    --benchmark_out=$OUT/$name.json --benchmark_out_format=json > $OUT/$name.txt 2>&1
  echo "$name rc=$? $(date +%T)"
}
date +%T
run before-c2 bench-before 2
run now-c2 bench-now 2
run before-c1 bench-before 1
run now-c1 bench-now 1
run now-c1-sorted bench-now 1 --vertex-order=sorted
run before-c1-2 bench-before 1
run now-c1-2 bench-now 1
opts="-cl-std=CL1.2 -DSKIN_VERTICES_PER_ITEM=4 -DSKIN_ITEMS_PER_GROUP=64 -DSKIN_COALESCED=1 -DSKIN_LOCAL_PALETTE=1 -DSKIN_LOCAL_TILES=1 -DMORPH_VERTICES_PER_ITEM=256"
for v in before now; do
  timeout 120 bin/ptxdump "$opts" kernels-$v/linear_blend_skinning.cl kernels-$v/dual_quaternion_skinning.cl kernels-$v/morph_targets.cl > $OUT/ptx-$v.ptx 2> $OUT/ptx-$v.log
  echo "ptx $v rc=$? $(date +%T)"
done
cd $OUT && for f in ptx-*.ptx; do grep -c "ld.shared.v4" $f; grep -c "ld.shared.f32" $f; done > ptx-counts.txt
tar czf all.tgz *.json *.txt *.log *.ptx && rm -f *.json *.ptx
