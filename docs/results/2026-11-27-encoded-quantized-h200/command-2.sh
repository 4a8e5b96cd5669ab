#!/bin/bash
export LD_LIBRARY_PATH=$PWD/build-gpu/lib
mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 > /tmp/icd/nvidia.icd; export OCL_ICD_VENDORS=/tmp/icd
cd build-gpu
SKINSERVE_OPENCL_DEVICE=gpu timeout 200 bin/skinserve_opencl_tests > $OUT/opencl-tests-verbose.txt 2>&1; echo "rc=$?" >> $OUT/opencl-tests-verbose.txt
run_service() {  # $1 before|now  $2 rest encoding  $3 answer encoding
  rm -f /tmp/port
  taskset -c 0,1 bin/skinserve-$1 --listen 127.0.0.1:0 --port-file /tmp/port --log-level warn --shm-dir /dev/shm \
    --threads 2 --opencl-device gpu > $OUT/server2-$1-$2-$3.log 2>&1 &
  local pid=$!
  for i in $(seq 100); do [ -s /tmp/port ] && break; sleep 0.2; done
  local rest=""; [ "$2" != float32 ] && rest="--rest-encoding $2"
  echo "taskset -c 2-15 bin/load-$1 --backends opencl --vertices 1600000 --bones 4 --streams 4 --window 2 --duration 5 --warmup 1 --data-planes grpc,shm --encoding $3 $rest" >> $OUT/service2-commands.txt
  timeout 60 taskset -c 2-15 bin/load-$1 --target 127.0.0.1:$(cat /tmp/port) --backends opencl --vertices 1600000 --bones 4 \
    --streams 4 --window 2 --duration 5 --warmup 1 --data-planes grpc,shm --encoding $3 $rest \
    --json $OUT/service2-$1-$2-$3.json > $OUT/service2-$1-$2-$3.txt 2>&1
  kill $pid; wait $pid 2>/dev/null
}
run_service before float32 float32
run_service now quantized16 snorm16
run_service before float32 snorm16
run_service now float32 float32
run_service now quantized16 snorm16
cd $OUT && tar czf all2.tgz *
