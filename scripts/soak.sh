#!/usr/bin/env bash
# Soak: a real skinserve under open-loop load near its capacity for --minutes N, with
# correctness checks (every 10th answer against the float64 reference), mesh churn (more
# meshes than --mesh-budget-mb holds: evictions, NOT_FOUND, re-uploads) and clients killed
# with SIGKILL mid-stream at random. Samples the server's RSS, threads and open fds every
# 5 s into $out/samples.csv. Fails on a wrong answer, a lost frame (sent, neither answered
# nor reported failed), a frame error other than NOT_FOUND (eviction) / RESOURCE_EXHAUSTED
# (full queue), more NOT_FOUND than re-uploading a lost mesh allows, or growth after the warm-up (the first fifth of the run, at least 30 s)
# beyond: RSS +64 MiB, threads +8, fds +32 over the warm-up's maximum.
#   scripts/soak.sh --minutes 2 [--out DIR] [--seed S]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
minutes=2 out="$build/soak" seed=$$
while [ $# -gt 0 ]; do
  case "$1" in
    --minutes) minutes=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    *) echo "usage: soak.sh --minutes N [--out DIR] [--seed S]" >&2; exit 2 ;;
  esac
done
RANDOM=$seed
[ -n "${SKINSERVE_SOAK_NO_BUILD:-}" ] || bash "$root/scripts/build.sh" >/dev/null
server_bin="$build/bin/skinserve"
load_bin="$build/bin/skinserve-load"
cli_bin="$build/bin/skinserve-cli"
mkdir -p "$out"
rm -f "$out"/*.json "$out"/*.log "$out/samples.csv"

# Four meshes of ~2.1 MiB (60k vertices, 2 influences, normals) churn through 8 MiB.
mesh_args=(--vertices 60000 --bones 2 --joints 77 --normals)
rm -f "$out/port"
"$server_bin" --listen 127.0.0.1:0 --port-file "$out/port" --threads 1 --mesh-budget-mb 8 \
  --log-level warn >"$out/server.log" 2>&1 &
server=$!
children=()
cleanup() {
  for pid in "${children[@]}"; do kill -9 "$pid" 2>/dev/null || true; done
  kill -9 "$server" 2>/dev/null || true
}
trap cleanup EXIT
# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"
if ! port=$(wait_for_port "$out/port" "$server" 120); then
  tail -20 "$out/server.log" >&2
  exit 1
fi
target="127.0.0.1:$port"
# The server is SERVING once its port is written: one frame must go through.
if ! "$load_bin" --target "$target" --backends serial "${mesh_args[@]}" --frames 1 --warmup 0 \
  >"$out/first-frame.log" 2>&1; then
  echo "soak: the first frame failed:" >&2
  tail -20 "$out/first-frame.log" "$out/server.log" >&2
  exit 1
fi

# Capacity: closed-loop frames/s of the server's one compute thread; the soak runs 4
# streams at 80 % of it in total.
"$load_bin" --target "$target" --backends sse "${mesh_args[@]}" --streams 4 --window 2 \
  --duration 5 --warmup 1 --json "$out/capacity.json" >"$out/capacity.log" 2>&1 || true
capacity=$(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); r=r["results"][0] if isinstance(r,dict) and "results" in r else r[0]; print(r["frames"]/r["seconds"])' "$out/capacity.json")
rate=$(python3 -c "print(max(1.0, 0.8 * $capacity / 4))")
echo "soak: ${minutes} min against $target; capacity ${capacity%.*} frames/s, 4 streams x ${rate} frames/s"

sample() {  # seconds rss_kib threads fds
  local rss threads fds
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$server/status")
  threads=$(awk '/^Threads:/ {print $2}' "/proc/$server/status")
  fds=$(ls "/proc/$server/fd" | wc -l)
  echo "$1,$rss,$threads,$fds" >>"$out/samples.csv"
}
echo "seconds,rss_kib,threads,fds" >"$out/samples.csv"

total=$((minutes * 60))
start=$SECONDS
epoch=0
while [ $((SECONDS - start)) -lt "$total" ]; do
  left=$((total - (SECONDS - start)))
  length=$((left < 20 ? left : 20))
  [ "$length" -ge 3 ] || break
  # Two checked clients on meshes that take turns (seeds 1..4), two streams each.
  for c in 0 1; do
    mesh_seed=$(((epoch * 2 + c) % 4 + 1))
    "$load_bin" --target "$target" --backends sse "${mesh_args[@]}" --seed "$mesh_seed" \
      --streams 2 --window 4 --rate "$rate" --check-every 10 --warmup 0 \
      --duration "$length" --json "$out/epoch$epoch-$c.json" >"$out/epoch$epoch-$c.log" 2>&1 &
    children+=($!)
  done
  # A victim: killed with SIGKILL at a random moment, frames in flight.
  "$load_bin" --target "$target" --backends sse "${mesh_args[@]}" --seed $((epoch % 4 + 1)) \
    --streams 2 --window 8 --rate "$rate" --warmup 0 --duration 600 >/dev/null 2>&1 &
  victim=$!
  children+=($victim)
  kill_at=$((SECONDS + 1 + RANDOM % (length - 1)))
  end=$((SECONDS + length))
  while [ $SECONDS -lt $end ]; do
    sample $((SECONDS - start))
    if [ $SECONDS -ge $kill_at ] && kill -0 $victim 2>/dev/null; then kill -9 $victim; fi
    sleep 5
  done
  kill -9 $victim 2>/dev/null || true
  wait "${children[@]}" 2>/dev/null || true
  children=()
  kill -0 "$server" 2>/dev/null || { echo "soak: the server died" >&2; exit 1; }
  epoch=$((epoch + 1))
done
sample $((SECONDS - start))
# Churn happened: the server evicted meshes (and the clients uploaded them again).
"$cli_bin" --target "$target" stats >"$out/stats.txt" 2>&1 || true
evictions=$(grep -o 'evictions [0-9]*' "$out/stats.txt" | awk '{print $2}')
echo "soak: server stats at the end: $(grep -o 'meshes [0-9]*.*evictions [0-9]*' "$out/stats.txt")"
kill -TERM "$server"
wait "$server" && server_exit=0 || server_exit=$?

python3 - "$out" "$total" "$server_exit" "${evictions:-0}" <<'PY'
import csv, glob, json, sys
out, total, server_exit, evictions = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
problems = []
if evictions == 0:
    problems.append("no mesh was evicted: the run had no mesh churn")
sent = answered = errors = checked = 0
codes = {}
for path in sorted(glob.glob(f"{out}/epoch*.json")):
    data = json.load(open(path))
    for r in (data["results"] if isinstance(data, dict) and "results" in data else data):
        sent += r["sent"]; answered += r["frames"]; checked += r["checked"]
        for code, n in r["errors"].items():
            codes[code] = codes.get(code, 0) + n
            errors += n
        if r["mismatches"]:
            problems.append(f"{path}: {r['mismatches']} wrong answers")
        if r["frames"] + sum(r["errors"].values()) < r["sent"]:
            problems.append(f"{path}: {r['sent'] - r['frames'] - sum(r['errors'].values())} frames lost")
for code in codes:
    if code not in ("NOT_FOUND", "RESOURCE_EXHAUSTED"):
        problems.append(f"{codes[code]} frames failed with {code}")
# A lost mesh goes again from the load client, once per loss: each eviction may fail at most
# the frames in flight and those sent while it went again (2 x window + 1) on each of the 4
# checked streams, not the rest of the run.
not_found_limit = evictions * 4 * (2 * 4 + 1)
if codes.get("NOT_FOUND", 0) > not_found_limit:
    problems.append(f"{codes['NOT_FOUND']} frames failed NOT_FOUND over {evictions} evictions "
                    f"(at most {not_found_limit}): a lost mesh was not uploaded again")
rows = [tuple(map(int, row)) for row in list(csv.reader(open(f"{out}/samples.csv")))[1:]]
warm = max(30, total // 5)
early = [r for r in rows if r[0] <= warm] or rows[:1]
late = [r for r in rows if r[0] > warm]
limits = {"rss_kib": 64 * 1024, "threads": 8, "fds": 32}
summary = {}
for i, name in enumerate(["rss_kib", "threads", "fds"], start=1):
    base = max(r[i] for r in early)
    peak = max((r[i] for r in late), default=base)
    summary[name] = (rows[0][i], base, peak, rows[-1][i])
    if peak > base + limits[name]:
        problems.append(f"{name} grew after the warm-up: {base} -> {peak} (margin {limits[name]})")
if server_exit != 0:
    problems.append(f"the server exited {server_exit} on SIGTERM")
print(f"soak: {total} s, {sent} frames sent, {answered} answered, {errors} failed {codes}, "
      f"{checked} checked against the reference")
for name, (first, base, peak, last) in summary.items():
    print(f"soak: {name}: start {first}, warm-up max {base}, max after warm-up {peak}, end {last}")
for p in problems:
    print("soak: FAIL:", p)
sys.exit(1 if problems else 0)
PY
