#!/usr/bin/env bash
# Characters per server in the set-ups docs/serving/capacity.md reports (60 fps streams of
# 25k vertices x 2 bones, p99 within one frame and nothing dropped), each with its own
# server on loopback, over both data planes side by side (gRPC, and shared memory: the
# vertices written into each stream's region in /dev/shm):
#   shared    server and load client on the same two cores (taskset -c 0,1)
#   pinned    server on core 0 (--threads 1), load client on core 1 (backend sse)
#   wide      server on cores 0,1 (--threads 2), load client on cores 2.. (a bigger machine)
#   transport 100k x 2, 8 streams, window 4, every backend, on cores 0,1 for both
# usage: scripts/capacity.sh [shared|pinned|wide|transport ...]   (default: shared pinned)
# Env: SKINSERVE_BIN (folder with skinserve, skinserve-cli, skinserve-load; default build's),
#      CAPACITY_SECONDS (measured seconds per probe, default 3).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
server_bin=${SKINSERVE_BIN:+$SKINSERVE_BIN/skinserve}
load_bin=${SKINSERVE_BIN:+$SKINSERVE_BIN/skinserve-load}
server_bin=${server_bin:-$root/build/bin/skinserve}
load_bin=${load_bin:-$root/build/bin/skinserve-load}
seconds=${CAPACITY_SECONDS:-3}
cores=$(nproc)

# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"

# run_setup NAME SERVER_CPUS LOAD_CPUS SERVER_ARGS -- LOAD_ARGS...
run_setup() {
  local name=$1 server_cpus=$2 load_cpus=$3 server_args=$4
  shift 5
  local port log pid port_file socket_dir
  log=$(mktemp)
  port_file=$(mktemp -u)
  # The load client talks to the server's Unix socket: shared-memory regions are served
  # there only (docs/serving/shared-memory.md#ownership).
  socket_dir=$(mktemp -d)
  # shellcheck disable=SC2086 # server_args is a list of flags
  taskset -c "$server_cpus" "$server_bin" --listen "127.0.0.1:0,unix:$socket_dir/grpc.sock" \
    --port-file "$port_file" --log-level warn $server_args >"$log" 2>&1 &
  pid=$!
  if ! port=$(wait_for_port "$port_file" "$pid" 120); then
    echo "$name: the server did not start serving:" >&2
    cat "$log" >&2
    exit 1
  fi
  rm -f "$port_file"
  echo "== $name: server on cpus $server_cpus ($server_args; TCP port $port), load client on" \
    "cpus $load_cpus"
  echo "   $ taskset -c $load_cpus skinserve-load --target unix:$socket_dir/grpc.sock $*"
  local status=0
  taskset -c "$load_cpus" "$load_bin" --target "unix:$socket_dir/grpc.sock" "$@" || status=$?
  kill -TERM "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  rm -rf "$socket_dir"
  if [ $status -ne 0 ]; then
    echo "   (load client exit $status; server log:)"
    tail -5 "$log"
  fi
  rm -f "$log"
  echo
}

probe=(--duration "$seconds" --warmup 0.5 --check-every 20 --data-planes grpc,shm)
for setup in "${@:-shared pinned}"; do
  for s in $setup; do
    case "$s" in
      shared)
        run_setup shared 0,1 0,1 "" -- --capacity --capacity-max-streams 256 \
          --modes float32,snorm16x16 "${probe[@]}"
        ;;
      pinned)
        run_setup pinned 0 1 "--threads 1" -- --backends sse --vertices 25000 --bones 2 --rate 60 \
          --streams 1 "${probe[@]}"
        run_setup pinned 0 1 "--threads 1" -- --backends sse --capacity \
          --capacity-max-streams 256 "${probe[@]}"
        ;;
      wide)
        [ "$cores" -ge 4 ] || { echo "wide: needs at least 4 cores"; continue; }
        run_setup wide 0,1 "2-$((cores - 1))" "--threads 2" -- --capacity \
          --capacity-max-streams 512 --modes float32,snorm16x16 "${probe[@]}"
        ;;
      transport)
        run_setup transport 0,1 0,1 "" -- --backends all --vertices 100000 --bones 2 \
          --streams 8 --window 4 --duration 3 --warmup 1 --data-planes grpc,shm
        ;;
      *) echo "unknown set-up '$s'" >&2; exit 2 ;;
    esac
  done
done
