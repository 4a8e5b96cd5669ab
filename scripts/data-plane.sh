#!/usr/bin/env bash
# The engine against the service over both data planes, in one sitting (issue 25): what
# skinserve-bench gets from a backend alone, then what a client gets through a skinserve
# on this host over gRPC and over shared memory (each stream's region in --shm-dir), at
# 400k and 1.6M vertices x 4 bones; then characters held at 60 fps (25k x 2) over both.
# Raw output (bench JSON, load JSON, the commands, the machine) goes to OUT; the tables
# in docs/serving/shared-memory.md are generated from it (scripts/docs-tables.py).
#   scripts/data-plane.sh OUT [options]
#     --backend ID          (default simd-openmp)
#     --opencl-device DEV   for the OpenCL backends (default: the server's default)
#     --server-cpus LIST    taskset for the server (default: all, sharing the cores)
#     --load-cpus LIST      taskset for the load client (default: all)
#     --threads N           the server's compute threads (default: its own default)
#     --streams N           streams of the throughput runs (default 2; window 2)
#     --no-capacity         skip the capacity search
# Env: SKINSERVE_BIN (folder with skinserve, skinserve-load, skinserve-bench; default the
# build's bin/), DATA_PLANE_SECONDS (measured seconds per run, default 5),
# SKINSERVE_SHM_DIR (default /dev/shm).
set -euo pipefail
out=${1:?usage: data-plane.sh OUT [options]}
shift
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin=${SKINSERVE_BIN:-$root/build/bin}
seconds=${DATA_PLANE_SECONDS:-5}
shm_dir=${SKINSERVE_SHM_DIR:-/dev/shm}
backend=simd-openmp device="" server_cpus="" load_cpus="" threads="" streams=2 capacity=1
while [ $# -gt 0 ]; do
  case "$1" in
    --backend) backend=$2; shift 2 ;;
    --opencl-device) device=$2; shift 2 ;;
    --server-cpus) server_cpus=$2; shift 2 ;;
    --load-cpus) load_cpus=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --streams) streams=$2; shift 2 ;;
    --no-capacity) capacity=0; shift ;;
    *) echo "data-plane: unknown option $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$out"
# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"
pin() { if [ -n "$1" ]; then echo "taskset -c $1"; fi; }
{
  date -u +%Y-%m-%dT%H:%MZ
  lscpu | grep -E 'Model name|^CPU\(s\)|L3' || true
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || true
} >"$out/machine.txt"
: >"$out/command.txt"
run() {  # logs the command (paths as in the repository and OUT), then runs it
  echo "$*" | sed "s#$root/##g; s#$out/#OUT/#g" >>"$out/command.txt"
  "$@"
}

# 1. The engine alone: the backend on the same threads the server gets.
bench_threads=()
[ -n "$threads" ] && bench_threads=(env "OMP_NUM_THREADS=$threads")
device_flag=()
[ -n "$device" ] && device_flag=(--opencl-device="$device")
# shellcheck disable=SC2046 # pin prints the taskset words or nothing
run "${bench_threads[@]}" $(pin "$server_cpus") "$bin/skinserve-bench" --backends="$backend" \
  --vertices=400000,1600000 --bones=4 "${device_flag[@]}" --benchmark_repetitions=3 \
  --benchmark_report_aggregates_only=true --benchmark_min_time=1 \
  --benchmark_filter="BM_Skin/$backend/" \
  --benchmark_out="$out/bench.json" --benchmark_out_format=json | tee "$out/bench.txt"

# 2. The service: one server, both data planes side by side in each load run.
# The load client talks to the server's Unix socket (both data planes): shared-memory
# regions are served there only (docs/serving/shared-memory.md#ownership).
socket_dir=$(mktemp -d)
target="unix:$socket_dir/grpc.sock"
server_args=(--listen "127.0.0.1:0,$target" --log-level warn --shm-dir "$shm_dir")
[ -n "$threads" ] && server_args+=(--threads "$threads")
[ -n "$device" ] && server_args+=(--opencl-device "$device")
port_file=$(mktemp -u)
log=$(mktemp)
# shellcheck disable=SC2046
$(pin "$server_cpus") "$bin/skinserve" "${server_args[@]}" --port-file "$port_file" \
  >"$log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$log" "$port_file" "$socket_dir"' EXIT
port=$(wait_for_port "$port_file" "$server" 180) || { cat "$log"; exit 1; }
echo "$(pin "$server_cpus")${server_cpus:+ }skinserve ${server_args[*]}  (port $port)" >>"$out/command.txt"
for vertices in 400000 1600000; do
  # shellcheck disable=SC2046
  run $(pin "$load_cpus") "$bin/skinserve-load" --target "$target" --backends "$backend" \
    --vertices "$vertices" --bones 4 --streams "$streams" --window 2 --duration "$seconds" \
    --warmup 1 --data-planes grpc,shm --shm-dir "$shm_dir" \
    --json "$out/service-$vertices.json" | tee "$out/service-$vertices.txt"
done
if [ "$capacity" = 1 ]; then
  # shellcheck disable=SC2046
  run $(pin "$load_cpus") "$bin/skinserve-load" --target "$target" --capacity \
    --backends "$backend" --capacity-max-streams 1024 --duration 3 --warmup 0.5 \
    --check-every 20 --data-planes grpc,shm --shm-dir "$shm_dir" \
    --json "$out/capacity.json" | tee "$out/capacity.txt"
fi
echo "data-plane: results in $out"
