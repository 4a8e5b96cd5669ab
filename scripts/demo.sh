#!/usr/bin/env bash
# Builds skinserve, starts the server on loopback, streams the paper's main case (100k
# vertices, 2 bones, 77 joints) on every backend through the real service, prints the
# table, then the fastest CPU backend over both data planes (gRPC, and shared memory on
# the same host), and stops the server. Extra arguments go to the load runs.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
bash "$root/scripts/build.sh"

# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"
log=$(mktemp)
port_file=$(mktemp -u)
# A Unix socket too: shared-memory regions are served there only.
socket_dir=$(mktemp -d)
"$build/bin/skinserve" --listen "127.0.0.1:0,unix:$socket_dir/grpc.sock" \
  --port-file "$port_file" --log-level warn >"$log" 2>&1 &
server=$!
stop() {
  kill -TERM "$server" 2>/dev/null || true
  wait "$server" 2>/dev/null || true
  rm -rf "$log" "$port_file" "$socket_dir"
}
trap stop EXIT
if ! port=$(wait_for_port "$port_file" "$server" 120); then
  echo "demo: the server did not start serving; its log:" >&2
  cat "$log" >&2
  exit 1
fi
target="127.0.0.1:$port"
echo "skinserve on $target; backends:"
"$build/bin/skinserve-cli" --target "$target" backends
echo
"$build/bin/skinserve-load" --target "$target" --backends all --vertices 100000 \
  --bones 2 --streams 2 --window 4 --duration 3 --warmup 1 --check-every 25 "$@"
echo
echo "The two data planes side by side: vertices in the gRPC answers, or written by the"
echo "server straight into each stream's shared-memory region (same host, /dev/shm; the"
echo "client on the server's Unix socket, where regions are served):"
"$build/bin/skinserve-load" --target "unix:$socket_dir/grpc.sock" --backends simd-openmp,passthrough \
  --data-planes grpc,shm --vertices 100000 --bones 2 --streams 2 --window 4 --duration 3 \
  --warmup 1 --check-every 25 "$@"
echo
"$build/bin/skinserve-cli" --target "$target" verify
