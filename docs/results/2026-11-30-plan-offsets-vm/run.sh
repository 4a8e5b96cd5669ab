#!/usr/bin/env bash
# Main (BASE_BIN) against this change (NEW_BIN), alternated, three rounds, on the VM:
# single characters over gRPC, StreamSkin into shared memory and the frame socket, then
# ticks of 64 over the two shared-memory planes; server on core 0 with one compute thread,
# load on core 1, 2 s of warm-up left out. From the repository's root: bash run.sh OUT
set -euo pipefail
out=${1:?usage: run.sh OUT}
for round in 1 2 3; do
  for build in base new; do
    bin=$BASE_BIN; [ "$build" = new ] && bin=$NEW_BIN
    SKINSERVE_BIN=$bin bash scripts/frame-cost.sh "$out/single-$build-$round" --backend simd \
      --threads 1 --server-cpus 0 --load-cpus 1 --streams 32 --warmup 2 --seconds 6 \
      --planes grpc,shm,socket >/dev/null
    SKINSERVE_BIN=$bin bash scripts/frame-cost.sh "$out/tick-$build-$round" --backend simd \
      --threads 1 --server-cpus 0 --load-cpus 1 --streams 2 --warmup 2 --seconds 6 \
      --planes shm,socket --extra "--characters-per-tick 64" >/dev/null
  done
done
