#!/bin/bash
# One device call: OpenCL correctness on the GPU (new quantized and encode kernels), issue 28's
# DQ target on the Xeon (before 4de5302 vs now, alternated), issue 29's GPU rows and the
# service through PCIe (before vs now).
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
nproc > $OUT/nproc.txt; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv > $OUT/gpu.txt 2>&1
lscpu > $OUT/lscpu.txt
SKINSERVE_OPENCL_DEVICE=gpu timeout 170 bin/skinserve_opencl_tests --gtest_brief=1 > $OUT/opencl-tests.txt 2>&1; echo "rc=$?" >> $OUT/opencl-tests.txt
timeout 100 bin/skinserve_backend_tests --gtest_filter='*Quantized*:*Hemisphere*' --gtest_brief=1 > $OUT/backend-tests.txt 2>&1; echo "rc=$?" >> $OUT/backend-tests.txt
tail -3 $OUT/opencl-tests.txt $OUT/backend-tests.txt
for rep in 1 2 3; do
for b in before now; do
  timeout 60 bin/bench-$b --backends=simd-openmp --vertices=400000 --bones=4 --methods=linear,dual-quaternion \
    --benchmark_min_time=0.3 --benchmark_repetitions=5 --benchmark_enable_random_interleaving=true \
    --benchmark_filter='BM_Skin(Normals)?(DualQuaternion)?/' --benchmark_format=json > $OUT/dq16-$b-$rep.json 2>/dev/null
  timeout 60 taskset -c 2 bin/bench-$b --backends=simd --vertices=400000 --bones=4 --methods=linear,dual-quaternion \
    --benchmark_min_time=0.2 --benchmark_repetitions=5 --benchmark_enable_random_interleaving=true \
    --benchmark_filter='BM_Skin(Normals)?(DualQuaternion)?/' --benchmark_format=json > $OUT/dq1-$b-$rep.json 2>/dev/null
done
done
echo dq done
timeout 120 bin/bench-now --opencl-device=gpu --backends=opencl --vertices=1600000 --bones=4 --quantized \
  --encoding=float16,snorm16 --streams=4 --benchmark_repetitions=3 --benchmark_min_time=0.2 \
  --benchmark_out=$OUT/gpu-now.json --benchmark_out_format=json > $OUT/gpu-now.txt 2>&1
timeout 60 bin/bench-before --opencl-device=gpu --backends=opencl --vertices=1600000 --bones=4 --streams=4 \
  --benchmark_repetitions=3 --benchmark_min_time=0.2 --benchmark_filter='BM_Skin(Streams)?/' \
  --benchmark_out=$OUT/gpu-before.json --benchmark_out_format=json > $OUT/gpu-before.txt 2>&1
echo bench done
run_service() {  # $1 before|now  $2 rest encoding  $3 answer encoding
  rm -f /tmp/port
  taskset -c 0,1 bin/skinserve-$1 --listen 127.0.0.1:0 --port-file /tmp/port --log-level warn --shm-dir /dev/shm \
    --threads 2 --opencl-device gpu > $OUT/server-$1-$2-$3.log 2>&1 &
  local pid=$!
  for i in $(seq 100); do [ -s /tmp/port ] && break; sleep 0.2; done
  local rest=""; [ "$2" != float32 ] && rest="--rest-encoding $2"
  echo "taskset -c 2-15 bin/load-$1 --backends opencl --vertices 1600000 --bones 4 --streams 4 --window 2 --duration 5 --warmup 1 --check-every 50 --data-planes grpc,shm --encoding $3 $rest" >> $OUT/service-commands.txt
  timeout 90 taskset -c 2-15 bin/load-$1 --target 127.0.0.1:$(cat /tmp/port) --backends opencl --vertices 1600000 --bones 4 \
    --streams 4 --window 2 --duration 5 --warmup 1 --check-every 50 --data-planes grpc,shm --encoding $3 $rest \
    --json $OUT/service-$1-$2-$3.json > $OUT/service-$1-$2-$3.txt 2>&1
  kill $pid; wait $pid 2>/dev/null
}
run_service before float32 float32
run_service now float32 float32
run_service now float32 snorm16
run_service now quantized16 snorm16
run_service before float32 snorm16
run_service now quantized16 float16
echo service done
cd $OUT && tar czf all.tgz *.json *.txt *.log && rm -f *.json *.log
