#!/usr/bin/env bash
# Issue 41's measurements in one sitting: what a small frame costs the server, single
# characters against ticks, and a baseline build against this one, alternately.
#   scripts/small-frames.sh OUT [options]
#     --new DIR          folder with this build's skinserve and skinserve-load (default build/bin)
#     --base DIR         a baseline build's folder (optional): its frame cost and capacity too
#     --backend ID       (default simd-openmp)
#     --threads N        the server's compute threads (default 2)
#     --server-cpus LIST (default 0,1)   --load-cpus LIST (default 2-15)
#     --streams N        single-character streams of the frame-cost runs (default 64)
#     --tick N           characters per tick (default 64)
#     --tick-streams N   streams of the tick frame-cost runs (default 4)
#     --repeats N        frame-cost runs per build, alternating (default 2)
#     --planes LIST      this build's data planes (default grpc,shm; socket: the frame socket;
#                        the baseline runs grpc,shm)
#     --no-capacity      skip the capacity searches
#     --capacities LIST  which of base,new,tick (default all three; base needs --base)
# Writes OUT/cost-{base,new}-R (scripts/frame-cost.sh), OUT/cost-tick-R, OUT/capacity-*.json
# and .txt, OUT/command.txt, OUT/machine.txt, and OUT/summary.csv (one row per run).
set -euo pipefail
out=${1:?usage: small-frames.sh OUT [options]}
shift
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
new=$root/build/bin base="" backend=simd-openmp threads=2 server_cpus=0,1 load_cpus=2-15
streams=64 tick=64 tick_streams=4 repeats=2 capacity=1 capacities=base,new,tick planes=grpc,shm
while [ $# -gt 0 ]; do
  case "$1" in
    --new) new=$2; shift 2 ;;
    --base) base=$2; shift 2 ;;
    --backend) backend=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --server-cpus) server_cpus=$2; shift 2 ;;
    --load-cpus) load_cpus=$2; shift 2 ;;
    --streams) streams=$2; shift 2 ;;
    --tick) tick=$2; shift 2 ;;
    --tick-streams) tick_streams=$2; shift 2 ;;
    --repeats) repeats=$2; shift 2 ;;
    --planes) planes=$2; shift 2 ;;
    --no-capacity) capacity=0; shift ;;
    --capacities) capacities=$2; shift 2 ;;
    *) echo "small-frames: unknown option $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$out"
# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"
# shellcheck source-path=SCRIPTDIR source=lib/machine-info.sh
source "$root/scripts/lib/machine-info.sh"
write_machine_info "$out/machine.txt" "$root"
echo "scripts/small-frames.sh OUT --backend $backend --threads $threads --server-cpus $server_cpus" \
  "--load-cpus $load_cpus --streams $streams --tick $tick --tick-streams $tick_streams" \
  "--repeats $repeats --planes $planes --capacities $capacities${base:+ --base BASE}" \
  >"$out/command.txt"
echo "run,build,plane,frames,server CPU us/frame,server CPU us/character,compute us,CPU / compute,voluntary switches/frame,errors" \
  >"$out/summary.csv"

cost() {  # NAME BIN [frame-cost options]
  local name=$1 bin=$2
  shift 2
  SKINSERVE_BIN=$bin bash "$root/scripts/frame-cost.sh" "$out/$name" --backend "$backend" \
    --threads "$threads" --server-cpus "$server_cpus" --load-cpus "$load_cpus" "$@" |
    sed "s/^/$name /"
  local build=${name#cost-}
  build=${build%-*}
  tail -n +2 "$out/$name/summary.csv" | sed "s/^/$name,$build,/" >>"$out/summary.csv"
}
builds=(new)
[ -n "$base" ] && builds=(base new)
for r in $(seq "$repeats"); do
  for b in "${builds[@]}"; do
    bin=$new
    [ "$b" = base ] && bin=$base
    build_planes=$planes
    [ "$b" = base ] && build_planes=grpc,shm
    cost "cost-$b-$r" "$bin" --streams "$streams" --planes "$build_planes"
  done
  cost "cost-tick-$r" "$new" --streams "$tick_streams" --extra "--characters-per-tick $tick" \
    --planes "$planes"
done

[ "$capacity" = 1 ] || exit 0
capacity() {  # NAME BIN PLANES [skinserve-load options]
  local name=$1 bin=$2 planes=$3 socket_dir port_file log server
  shift 3
  socket_dir=$(mktemp -d)
  port_file=$(mktemp -u)
  log=$(mktemp)
  local socket_args=()
  [[ ",$planes," == *",socket,"* ]] && socket_args=(--frame-socket "$socket_dir/frames.sock")
  taskset -c "$server_cpus" "$bin/skinserve" --listen "127.0.0.1:0,unix:$socket_dir/grpc.sock" \
    --threads "$threads" --log-level warn --shm-max-regions-per-connection 4096 \
    --shm-max-regions 4096 "${socket_args[@]}" --port-file "$port_file" >"$log" 2>&1 &
  server=$!
  wait_for_port "$port_file" "$server" 180 >/dev/null || { cat "$log"; return 1; }
  local cmd=(taskset -c "$load_cpus" "$bin/skinserve-load" --target "unix:$socket_dir/grpc.sock"
    --capacity --backends "$backend" --vertices 25000 --bones 2 --duration 3 --warmup 0.5
    --check-every 20 --data-planes "$planes" "${socket_args[@]}" --json "$out/$name.json" "$@")
  echo "$name: ${cmd[*]}" | sed "s#$socket_dir#SOCKDIR#g; s#$out/#OUT/#g; s#$bin/##g" \
    >>"$out/command.txt"
  "${cmd[@]}" >"$out/$name.txt" 2>&1 || echo "$name failed (see $name.txt)"
  kill -TERM "$server"
  wait "$server" 2>/dev/null || true
  rm -rf "$socket_dir" "$port_file" "$log"
  grep -iE 'capacity|held' "$out/$name.txt" | tail -3 | sed "s/^/$name /"
}
wanted() { [[ ",$capacities," == *",$1,"* ]]; }
if [ -n "$base" ] && wanted base; then
  capacity capacity-base "$base" grpc,shm --capacity-max-streams 1024
fi
if wanted new; then capacity capacity-new "$new" "$planes" --capacity-max-streams 1024; fi
if wanted tick; then
  capacity capacity-tick "$new" "$planes" --characters-per-tick "$tick" --capacity-max-streams 64
fi
