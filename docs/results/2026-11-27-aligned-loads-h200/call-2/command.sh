#!/bin/bash
# Device call 2: bench-now2 (palette, joints and weights as aligned vector loads in the float and
# quantized kernels): local tiles 1/2/4 and the global palette, one chunk; the default 2 chunks;
# sorted order; then the OpenCL tests on the GPU; PTX of the quantized program.
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
rows='BM_(Skin|SkinNormals|SkinQuantized|SkinNormalsQuantized|SkinQuantizedWeights8)/opencl(-global)?/1600000/[14]/|BM_DeviceMemoryCopy'
common="--opencl-device=gpu --backends=opencl --vertices=1600000 --bones=1,4 --quantized --benchmark_repetitions=3 --benchmark_min_time=0.2"
run() {  # $1 name  $2 binary  $3 chunks  $4 tiles  $5.. extra flags
  local name=$1 bin=$2 chunks=$3 tiles=$4; shift 4
  echo "SKINSERVE_OPENCL_CHUNKS=$chunks SKINSERVE_OPENCL_LOCAL_TILES=$tiles bin/$bin $common --benchmark_filter='$rows' $*" >> $OUT/commands.txt
  SKINSERVE_OPENCL_CHUNKS=$chunks SKINSERVE_OPENCL_LOCAL_TILES=$tiles timeout 150 bin/$bin $common --benchmark_filter="$rows" "$@" \
    --benchmark_out=$OUT/$name.json --benchmark_out_format=json > $OUT/$name.txt 2>&1
  echo "$name rc=$? $(date +%T)"
}
date +%T
run now2-c1-t1 bench-now2 1 1 --opencl-global-palette
run now2-c1-t2 bench-now2 1 2
run now2-c1-t4 bench-now2 1 4
run now2-c2-t1 bench-now2 2 1
run now2-c1-t1-sorted bench-now2 1 1 --vertex-order=sorted
run before-c1-t1 bench-before 1 1
run now2-c1-t1-b bench-now2 1 1
SKINSERVE_OPENCL_DEVICE=gpu timeout 260 bin/skinserve_opencl_tests --gtest_brief=1 > $OUT/opencl-tests.txt 2>&1; echo "rc=$?" >> $OUT/opencl-tests.txt
tail -3 $OUT/opencl-tests.txt; date +%T
opts="-cl-std=CL1.2 -DSKIN_VERTICES_PER_ITEM=4 -DSKIN_ITEMS_PER_GROUP=64 -DSKIN_COALESCED=1 -DSKIN_LOCAL_PALETTE=1 -DSKIN_LOCAL_TILES=1 -DMORPH_VERTICES_PER_ITEM=256"
timeout 60 bin/ptxdump "$opts -DQSKIN_JOINT=uchar -DQSKIN_WEIGHT=ushort -DQSKIN_WEIGHT_STEPS=65535" kernels-now2/linear_blend_skinning.cl kernels-now2/quantized_skinning.cl > $OUT/ptx-q.ptx 2> $OUT/ptx-q.log
timeout 60 bin/ptxdump "$opts" kernels-now2/linear_blend_skinning.cl kernels-now2/dual_quaternion_skinning.cl kernels-now2/morph_targets.cl > $OUT/ptx-now2.ptx 2> $OUT/ptx-now2.log
cd $OUT && for f in ptx-*.ptx; do echo "$f v4shared $(grep -c 'ld.shared.v4' $f) f32shared $(grep -c 'ld.shared.f32' $f) local $(grep -c 'ld.local\|st.local' $f) ldg-v2 $(grep -c 'ld.global.*v2' $f) ldg-v4 $(grep -c 'ld.global.*v4' $f)"; done > ptx-counts.txt; cat ptx-counts.txt
tar czf all.tgz *.json *.txt *.log *.ptx && rm -f *.json *.ptx
