#!/usr/bin/env bash
# What a small frame costs the server beyond its skinning (issue 41): one server pinned to
# --server-cpus with --threads compute threads, the load client pinned elsewhere, a fixed
# open-loop load (default 32 streams of 25k x 2 at 60 fps) over each data plane in turn.
# Per plane: the server's CPU per frame and per character, its ratio to the frame's compute
# (skinserve-load --metrics-url) and the voluntary context switches per frame, summed over
# the server's threads from /proc/PID/task/*/status before and after the run.
#   scripts/frame-cost.sh OUT [options]
#     --backend ID          (default simd)
#     --server-cpus LIST    taskset for the server (default 0)
#     --load-cpus LIST      taskset for the load client (default 1)
#     --threads N           the server's compute threads (default 1)
#     --streams N           (default 32)     --rate FPS  per stream (default 60)
#     --vertices N          (default 25000)  --bones N   (default 2)
#     --seconds S           measured seconds per plane (default 6)
#     --warmup S            unmeasured seconds first, per plane (default 0: the start-up's
#                           first touches are measured; the switches count the warm-up's too)
#     --planes LIST         (default grpc,shm; socket: the frame socket, --frame-socket)
#     --extra "ARGS"        more skinserve-load arguments (e.g. --characters-per-tick 64)
#     --server-extra "ARGS" more skinserve arguments (e.g. --reflection=false)
# Env: SKINSERVE_BIN (default the build's bin/), SKINSERVE_SHM_DIR (default /dev/shm).
set -euo pipefail
out=${1:?usage: frame-cost.sh OUT [options]}
shift
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin=${SKINSERVE_BIN:-$root/build/bin}
shm_dir=${SKINSERVE_SHM_DIR:-/dev/shm}
backend=simd server_cpus=0 load_cpus=1 threads=1 streams=32 rate=60 vertices=25000 bones=2
seconds=6 warmup=0 planes=grpc,shm extra="" server_extra=""
while [ $# -gt 0 ]; do
  case "$1" in
    --backend) backend=$2; shift 2 ;;
    --server-cpus) server_cpus=$2; shift 2 ;;
    --load-cpus) load_cpus=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --streams) streams=$2; shift 2 ;;
    --rate) rate=$2; shift 2 ;;
    --vertices) vertices=$2; shift 2 ;;
    --bones) bones=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --warmup) warmup=$2; shift 2 ;;
    --planes) planes=$2; shift 2 ;;
    --extra) extra=$2; shift 2 ;;
    --server-extra) server_extra=$2; shift 2 ;;
    *) echo "frame-cost: unknown option $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$out"
# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"
# shellcheck source-path=SCRIPTDIR source=lib/machine-info.sh
source "$root/scripts/lib/machine-info.sh"
write_machine_info "$out/machine.txt" "$root"
: >"$out/command.txt"
rm -f "$out/summary.csv" "$out/summary.txt"

socket_dir=$(mktemp -d)
target="unix:$socket_dir/grpc.sock"
port_file=$(mktemp -u)
log=$(mktemp)
server_args=(--listen "127.0.0.1:0,$target" --metrics-listen 127.0.0.1:0 --log-level info
  --shm-dir "$shm_dir" --threads "$threads" --shm-max-regions-per-connection 256)
# The socket plane needs the server's frame socket (a build without it runs the others).
socket_args=()
[[ ",$planes," == *",socket,"* ]] && socket_args=(--frame-socket "$socket_dir/frames.sock")
server_args+=("${socket_args[@]}")
# shellcheck disable=SC2206 # split on purpose
server_args+=($server_extra)
taskset -c "$server_cpus" "$bin/skinserve" "${server_args[@]}" --port-file "$port_file" \
  >"$log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$log" "$port_file" "$socket_dir"' EXIT
wait_for_port "$port_file" "$server" 180 >/dev/null || { cat "$log"; exit 1; }
metrics_port=$(grep -o 'metrics on .*(port [0-9]*)' "$log" | head -1 | sed 's/.*(port //; s/)//')
metrics=${metrics_port:+127.0.0.1:$metrics_port}
[ -n "$metrics" ] || { echo "frame-cost: cannot find the metrics port" >&2; cat "$log"; exit 1; }
echo "taskset -c $server_cpus skinserve ${server_args[*]}" | sed "s#$socket_dir#SOCKDIR#g" \
  >>"$out/command.txt"

# Voluntary context switches over the server's threads (its metric: getrusage, so threads
# that ended count too, as a frame-socket connection's does): a thread blocked (waiting for
# the next frame, or handing one to another thread). Involuntary ones (preemption by
# whatever else runs on the server's cores) are left out: they say more about the machine.
switches() {
  python3 - "http://$metrics/metrics" <<'PY'
import sys, urllib.request
text = urllib.request.urlopen(sys.argv[1], timeout=10).read().decode()
key = 'skinserve_process_context_switches_total{kind="voluntary"} '
print(next(int(float(line[len(key):])) for line in text.splitlines() if line.startswith(key)))
PY
}
for plane in ${planes//,/ }; do
  before=$(switches)
  # shellcheck disable=SC2086,SC2206 # extra is split on purpose
  cmd=(taskset -c "$load_cpus" "$bin/skinserve-load" --target "$target" --backends "$backend"
    --vertices "$vertices" --bones "$bones" --streams "$streams" --rate "$rate"
    --duration "$seconds" --warmup "$warmup" --data-planes "$plane" --shm-dir "$shm_dir"
    "${socket_args[@]}"
    --metrics-url "http://$metrics/metrics" --check-every 50 $extra
    --json "$out/$plane.json")
  echo "${cmd[*]}" | sed "s#$socket_dir#SOCKDIR#g; s#$out/#OUT/#g; s#$bin/##g" >>"$out/command.txt"
  "${cmd[@]}" >"$out/$plane.txt"
  after=$(switches)
  python3 - "$out/$plane.json" "$before" "$after" "$plane" <<'EOF' | tee -a "$out/summary.txt"
import json, sys
rows = json.load(open(sys.argv[1]))
rows = rows["results"]
row = rows[0]
frames = int(row.get("server_frames") or row["frames"])
chars = frames * max(1, row.get("instances", 1) or 1)
sw = (int(sys.argv[3]) - int(sys.argv[2])) / frames
import os
csv = os.path.join(os.path.dirname(sys.argv[1]), "summary.csv")
new = not os.path.exists(csv)
with open(csv, "a") as f:
    if new:
        f.write("plane,frames,server CPU us/frame,server CPU us/character,compute us,"
                "CPU / compute,voluntary switches/frame,errors\n")
    f.write(f"{sys.argv[4]},{frames},{row.get('server_cpu_us_per_frame') or 0:.1f},"
            f"{row.get('server_cpu_us_per_character') or 0:.1f},"
            f"{1000 * row['server_ms']['compute']:.1f},"
            f"{row.get('server_cpu_over_compute') or 0:.2f},{sw:.2f},{row.get('errors') or 0}\n")
print(f"{sys.argv[4]:5s} frames {frames:7d}  cpu us/frame {row.get('server_cpu_us_per_frame') or 0:8.1f}"
      f"  cpu us/char {row.get('server_cpu_us_per_character') or 0:7.1f}"
      f"  compute us {1000 * row['server_ms']['compute']:6.1f}"
      f"  cpu/compute {row.get('server_cpu_over_compute') or 0:5.2f}"
      f"  switches/frame {sw:5.2f}  errors {row.get('errors') or 0}")
EOF
done
