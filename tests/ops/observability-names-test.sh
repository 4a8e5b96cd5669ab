#!/usr/bin/env bash
# The Grafana dashboard and the alert rules (deploy/observability/) name only metrics a
# real server exports: scrapes one started here and compares; promtool parses every query.
# usage: observability-names-test.sh SKINSERVE REPOSITORY_ROOT
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ $# -eq 2 ] || { echo "usage: $0 skinserve repository-root" >&2; exit 2; }
server=$1 root=$2
for tool in promtool curl python3; do
  command -v "$tool" >/dev/null || { echo "observability-names-test: SKIPPED: $tool missing (scripts/install-deps.sh)"; exit 77; }
done
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-observability.XXXXXX")
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
"$server" --listen 127.0.0.1:0 --port-file "$work/port" \
  --metrics-listen "127.0.0.1:$metrics_port" --threads 1 --log-level warn >"$work/server.log" 2>&1 &
server_pid=$!
wait_for_port "$work/port" "$server_pid" 60 >/dev/null || { echo "observability-names-test: FAILED: server not serving" >&2; exit 1; }
curl -sSf "http://127.0.0.1:$metrics_port/metrics" >"$work/metrics.txt"
python3 "$here/observability_names_check.py" "$work/metrics.txt" \
  "$root/deploy/observability/grafana-dashboard.json" "$root/deploy/observability/alerts.yaml" \
  "$(command -v promtool)"
