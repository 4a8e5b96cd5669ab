#!/usr/bin/env bash
# On the GPU machine's Xeon, from the repository root with build-xeon/ carried: main at af31640
# (base) against the renormalise change (new), alternated: skinserve-bench rows on one core
# (and the tick rows on two at once), then the service's ticks of 64 (simd, shared memory;
# server on cores 0,1 --threads 2, load on 2-15): a fixed load of 3 streams and the capacity.
set -uo pipefail
out=$OUT; here=build-xeon
export LD_LIBRARY_PATH=$here/lib
lscpu > "$out/machine.txt"; nproc >> "$out/machine.txt"
ROWS='BM_Skin(Normals)?/simd/(25000|400000)/(2|4)/|BM_SkinTick(Normals)?/simd/25000/'
for round in 1 2 3; do
  for b in base new; do
    taskset -c 2 $here/bin/skinserve-bench-$b --backends=simd --vertices=25000,400000 --bones=2,4 \
      --tick=64 --benchmark_filter="$ROWS" --benchmark_min_time=0.2 --benchmark_format=json \
      > "$out/bench-$b-$round.json" 2>/dev/null
    for c in 4 6; do
      taskset -c $c $here/bin/skinserve-bench-$b --backends=simd --vertices=25000 --bones=2 --tick=64 \
        --benchmark_filter='BM_SkinTickNormals' --benchmark_min_time=0.3 --benchmark_format=json \
        > "$out/bench2-$b-$round-core$c.json" 2>/dev/null &
    done
    wait
  done
done
serve() {  # BUILD
  sock=$(mktemp -d); mport=$((20000 + RANDOM % 20000)); pf=$(mktemp -u)
  taskset -c 0,1 "$here/bin/skinserve-$1" --listen "127.0.0.1:0,unix:$sock/g.sock" --threads 2 \
    --port-file "$pf" --metrics-listen "127.0.0.1:$mport" --shm-max-regions-per-connection 4096 \
    --shm-max-regions 4096 --log-level warn > "$out/server-$1.log" 2>&1 &
  pid=$!
  for _ in $(seq 600); do [ -s "$pf" ] && break; sleep 0.1; done
}
load() {  # NAME ARGS...
  local name=$1; shift
  taskset -c 2-15 $here/bin/skinserve-load --target "unix:$sock/g.sock" --vertices 25000 --bones 2 \
    --metrics-url "http://127.0.0.1:$mport/metrics" --json "$out/$name.json" "$@" > "$out/$name.txt" 2>&1
}
service() {
for round in 1 2; do
  for b in base new; do
    serve $b
    load "tick-fixed-$b-$round" --backends simd --characters-per-tick 64 --streams 3 --window 2 \
      --rate 60 --duration 5 --warmup 1 --data-planes shm --check-every 20
    load "tick-cap-$b-$round" --backends simd --characters-per-tick 64 --capacity \
      --capacity-max-streams 16 --duration 3 --data-planes shm --check-every 20
    kill -TERM $pid; wait $pid 2>/dev/null; rm -rf "$sock" "$pf"
    grep -iE "held|capacity" "$out/tick-cap-$b-$round.txt" | tail -2 | sed "s/^/$b $round /"
  done
done
}
export -f serve load service 2>/dev/null
service
cd "$out" && tar czf all.tgz ./*.json ./*.txt ./*.log && rm -f ./*.json tick-*.txt
python3 - <<'PY'
import json, tarfile, statistics, re, collections
t = tarfile.open("all.tgz")
rows = collections.defaultdict(list)
for m in t.getmembers():
    if not m.name.endswith(".json") or "bench" not in m.name: continue
    b = "new" if "-new-" in m.name else "base"
    for r in json.load(t.extractfile(m))["benchmarks"]:
        us = r.get("seconds_per_character", 0) * 1e6 or r["real_time"] * (1000 if r["time_unit"] == "ms" else 1)
        two = "bench2" in m.name
        rows[(r["name"].replace("/real_time", "") + (" [2 at once]" if two else ""), b)].append(us)
for (n, b), v in sorted(rows.items()):
    print(f"{n:60s} {b:5s} median {statistics.median(v):8.1f} us  {min(v):.1f}-{max(v):.1f}")
PY
