#!/usr/bin/env bash
# How often a server builds a stream's plan (StreamPlan::Build, counted by a perf uprobe on
# the binary's symbol) over 3 s of a steady load: 32 single-character streams at 60 fps
# (1,920 frames/s) over gRPC, StreamSkin into shared memory and the frame socket, then 2
# streams of ticks of 64 at 60 ticks/s (7,680 characters/s) over the two shared-memory planes.
# Server on core 0 (--threads 1), load on core 1. Needs root (perf probe).
# From the repository's root: BIN=build/bin bash plan-builds.sh > OUT/plan-builds-LABEL.csv
set -euo pipefail
bin=${BIN:?BIN: the bin/ folder of a build}
address=$(nm "$bin/skinserve" | grep ' T _ZN9skinserve6server10StreamPlan5Build' | cut -d' ' -f1)
perf probe -q -d 'probe_skinserve:plan_build' 2>/dev/null || true
perf probe -q -x "$bin/skinserve" -a "plan_build=0x$address"
echo "load,plane,offered per second,plan builds per second"
for load in single tick; do
  for plane in grpc shm socket; do
    [ "$load" = tick ] && [ "$plane" = grpc ] && continue
    dir=$(mktemp -d)
    taskset -c 0 "$bin/skinserve" --listen "unix:$dir/g.sock" --threads 1 --shm-dir /dev/shm \
      --shm-max-regions-per-connection 256 --frame-socket "$dir/f.sock" \
      --port-file "$dir/port" >"$dir/log" 2>&1 &
    server=$! streams=32 extra=() offered=1920
    [ "$load" = tick ] && streams=2 extra=(--characters-per-tick 64) offered=7680
    for _ in $(seq 100); do [ -s "$dir/port" ] && break; sleep 0.1; done
    taskset -c 1 "$bin/skinserve-load" --target "unix:$dir/g.sock" --backends simd \
      --vertices 25000 --bones 2 --streams $streams --rate 60 --duration 9 --warmup 0 \
      --data-planes "$plane" --frame-socket "$dir/f.sock" --shm-dir /dev/shm \
      "${extra[@]}" >"$dir/load.txt" 2>&1 &
    load_pid=$!
    sleep 5
    builds=$(perf stat -x, -e probe_skinserve:plan_build -p $server -- sleep 3 2>&1 |
      grep plan_build | cut -d, -f1)
    wait $load_pid
    kill -TERM $server; wait $server || true
    rm -rf "$dir"
    echo "$load,$plane,$offered,$((builds / 3))"
  done
done
perf probe -q -d 'probe_skinserve:plan_build'
