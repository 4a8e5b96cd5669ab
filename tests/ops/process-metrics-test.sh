#!/usr/bin/env bash
# The process_* series of a real server's /metrics against what this test reads of the
# same process itself, from /proc/PID and the cgroup file system: CPU seconds, resident
# and virtual memory, open and allowed descriptors (and open ones growing as clients
# connect and shrinking as they leave), the start time against when the test launched it,
# and skinserve_memory_limit_bytes against the cgroup's limit.
# usage: process-metrics-test.sh SKINSERVE
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ $# -eq 1 ] || { echo "usage: $0 skinserve" >&2; exit 2; }
server=$1
command -v python3 >/dev/null || { echo "process-metrics-test: SKIPPED: python3 missing"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-process-metrics.XXXXXX")
server_pid=""
cleanup() {
  local rc=$?
  if [ -n "$server_pid" ]; then kill -KILL "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  [ $rc -eq 0 ] || tail -20 "$work/server.log" 2>/dev/null || true
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT

metrics_port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
launched=$(date +%s.%N)
"$server" --listen 127.0.0.1:0 --port-file "$work/port" \
  --metrics-listen "127.0.0.1:$metrics_port" --threads 1 --log-level warn >"$work/server.log" 2>&1 &
server_pid=$!
grpc_port=$(wait_for_port "$work/port" "$server_pid" 60) || { echo "process-metrics-test: FAILED: server not serving" >&2; exit 1; }
python3 "$here/process_metrics_check.py" "http://127.0.0.1:$metrics_port/metrics" "$server_pid" \
  "$launched" "$grpc_port"
