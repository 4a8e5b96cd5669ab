#!/usr/bin/env bash
# The Prometheus endpoint of a real server, end to end:
#   1. a loaded server's exposition passes `promtool check metrics`, and its counters match
#      what skinserve-load sent (frames and vertices per backend, one histogram sample per
#      frame), a frame for an unknown mesh counts as a NOT_FOUND error, build_info carries
#      `skinserve --version`'s version;
#   2. a metrics port that is taken: the server refuses to start, naming the port;
#   3. scrapes during a SIGTERM drain: every answer is a whole exposition, a spread sample
#      of them passes promtool (or the connection is refused once the server is gone), and
#      the server exits 0;
#   4. --log-format json: every line the server logged is one JSON object.
# usage: metrics-test.sh SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"
if [ $# -ne 3 ]; then
  echo "usage: $0 skinserve skinserve-cli skinserve-load" >&2
  exit 2
fi
server=$1 cli=$2 load=$3
for tool in promtool curl python3; do
  command -v "$tool" >/dev/null || { echo "metrics-test: SKIPPED: $tool missing (scripts/install-deps.sh)"; exit 77; }
done
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-metrics.XXXXXX")
pids=()
say() { echo "metrics-test: $*"; }
fail() { echo "metrics-test: FAILED: $*" >&2; exit 1; }
cleanup() {
  local rc=$?
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; done
  if [ $rc -ne 0 ]; then
    for f in "$work"/*.log; do [ -f "$f" ] && { echo "--- $f"; tail -20 "$f"; }; done
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

metrics_port=$(free_port)
metrics="http://127.0.0.1:$metrics_port/metrics"
"$server" --listen 127.0.0.1:0 --port-file "$work/port" \
  --metrics-listen "127.0.0.1:$metrics_port" --threads 1 --log-format json \
  >"$work/server.log" 2>&1 &
server_pid=$!
pids+=("$server_pid")
grpc_port=$(wait_for_port "$work/port" "$server_pid" 60) || fail "server not serving"

# ---- 1. counters against what the load client sent --------------------------------------
streams=2 frames=40 vertices=5000
say "skinserve-load: serial and sse, $streams streams x $frames frames of $vertices vertices"
"$load" --target "127.0.0.1:$grpc_port" --backends serial,sse --vertices "$vertices" \
  --streams "$streams" --frames "$frames" --warmup 0 --check-every 1 \
  --json "$work/load.json" >"$work/load.log" 2>&1 || fail "skinserve-load failed"
# One frame (unary Skin) for a backend the server does not have: an INVALID_ARGUMENT error,
# counted under backend="other" (a client's made-up id never becomes a label value).
"$cli" --target "127.0.0.1:$grpc_port" skin --backend no-such-backend \
  >"$work/bad-backend.log" 2>&1 && fail "skin on an unknown backend succeeded"
curl -sSf "$metrics" >"$work/metrics.txt" || fail "GET $metrics"
say "promtool check metrics"
promtool check metrics <"$work/metrics.txt" || fail "promtool rejected the exposition"
version=$("$server" --version | awk '{print $2}')
python3 - "$work/metrics.txt" "$work/load.json" "$version" "$((streams * frames))" "$vertices" <<'PY' || fail "counters"
import json, re, sys
text, load, version = open(sys.argv[1]).read(), json.load(open(sys.argv[2])), sys.argv[3]
sent, vertices = int(sys.argv[4]), int(sys.argv[5])
samples = {}
for line in text.splitlines():
    if line and not line.startswith("#"):
        key, value = line.rsplit(" ", 1)
        samples[key] = float(value)
problems = []
def expect(key, want):
    got = samples.get(key)
    if got != want:
        problems.append(f"{key} = {got}, expected {want}")
for r in load["results"]:
    b = r["backend"]
    if r["frames"] != sent or r["errors"]:
        problems.append(f"skinserve-load {b}: {r['frames']} frames, errors {r['errors']}")
    expect(f'skinserve_frames_total{{backend="{b}"}}', r["frames"])
    expect(f'skinserve_vertices_total{{backend="{b}"}}', r["frames"] * vertices)
    for h in ("queue", "compute", "encode", "server"):
        expect(f'skinserve_frame_{h}_seconds_count{{backend="{b}"}}', r["frames"])
        expect(f'skinserve_frame_{h}_seconds_bucket{{backend="{b}",le="+Inf"}}', r["frames"])
expect('skinserve_frame_errors_total{backend="other",code="INVALID_ARGUMENT"}', 1)
expect(f'skinserve_build_info{{version="{version}"}}', 1)
expect("skinserve_serving", 1)
expect("skinserve_open_streams", 0)
expect("skinserve_queue_depth", 0)
expect('skinserve_upload_refusals_total{reason="max_uploads"}', 0)
for key in ("skinserve_meshes", "skinserve_mesh_bytes", "skinserve_upload_budget_bytes"):
    if not samples.get(key, 0) > 0:
        problems.append(f"{key} is not positive")
for r in load["results"]:
    counted = samples.get('skinserve_frames_total{backend="%s"}' % r["backend"])
    print(f"metrics-test: {r['backend']}: {r['frames']} frames sent, {counted} counted")
for p in problems:
    print("problem:", p)
sys.exit(1 if problems else 0)
PY

# ---- 2. a taken metrics port -------------------------------------------------------------
say "a second server on the same metrics port must refuse to start, naming the port"
rc=0
timeout 30 "$server" --listen "127.0.0.1:0" --metrics-listen "127.0.0.1:$metrics_port" \
  >"$work/taken.log" 2>&1 || rc=$?
[ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] || fail "second server: exit $rc (expected a start-up error)"
grep -q "port $metrics_port" "$work/taken.log" || fail "the error does not name port $metrics_port"
say "refused: $(grep -m1 "port $metrics_port" "$work/taken.log")"

# ---- 3. scrapes while the server drains ----------------------------------------------------
say "SIGTERM under load, scraping back to back until the server is gone"
"$load" --target "127.0.0.1:$grpc_port" --backends serial --vertices "$vertices" --streams 2 \
  --duration 5 --warmup 0 >"$work/drain-load.log" 2>&1 &
load_pid=$!
pids+=("$load_pid")
sleep 1
python3 - "$metrics" "$work/scrapes" <<'PY' &
import os, sys, time, urllib.request
url, out = sys.argv[1], sys.argv[2]
os.makedirs(out)
n = 0
deadline = time.time() + 30
while time.time() < deadline:
    try:
        body = urllib.request.urlopen(url, timeout=5).read()
        open(f"{out}/{n:05d}.txt", "wb").write(body)
        n += 1
    except Exception as e:  # refused once the server is gone: the end
        open(f"{out}/end", "w").write(repr(e))
        break
PY
scraper_pid=$!
for _ in $(seq 1 300); do  # SIGTERM once the scraper is at it
  [ -f "$work/scrapes/00003.txt" ] && break
  sleep 0.1
done
kill -TERM "$server_pid"
server_rc=0
wait "$server_pid" || server_rc=$?
wait "$scraper_pid" || fail "scraper"
{ kill -KILL "$load_pid" && wait "$load_pid"; } 2>/dev/null || true
[ "$server_rc" -eq 0 ] || fail "server exited $server_rc after SIGTERM"
[ -f "$work/scrapes/end" ] || fail "scrapes still answered 30 s after SIGTERM"
ls "$work"/scrapes/*.txt >/dev/null 2>&1 || fail "no scrape answered: $(cat "$work/scrapes/end")"
# Every scrape must be whole (it ends with the last metric); promtool checks the first and
# last 20, the first 20 while draining and 100 spread over the rest. (The scraper runs back
# to back, a few thousand scrapes; promtool on each took minutes.)
summary=$(python3 - "$work/scrapes" 2>&1 <<'PY'
import os, subprocess, sys
d = sys.argv[1]
files = sorted(f for f in os.listdir(d) if f.endswith(".txt"))
draining = []
for i, f in enumerate(files):
    text = open(os.path.join(d, f)).read()
    last = text.rstrip("\n").rsplit("\n", 1)[-1]
    if not last.startswith("skinserve_compute_threads "):
        sys.exit(f"scrape {f} is cut short: its last line is {last!r}")
    if "\nskinserve_serving 0\n" in text:
        draining.append(i)
n = len(files)
chosen = set(range(min(20, n))) | set(range(max(0, n - 20), n)) | set(draining[:20])
chosen |= {i * n // 100 for i in range(100)}
for i in sorted(chosen):
    with open(os.path.join(d, files[i]), "rb") as body:
        check = subprocess.run(["promtool", "check", "metrics"], stdin=body, capture_output=True)
    if check.returncode != 0:
        sys.exit(f"scrape {files[i]} during shutdown is not a valid exposition: {(check.stdout + check.stderr).decode(errors='replace')}")
print(n, len(draining), len(chosen))
PY
) || fail "$summary"
read -r n draining checked <<<"$summary"
[ "$n" -gt 0 ] || fail "no scrape answered"
say "$n scrapes around SIGTERM, all whole, $checked of them valid for promtool ($draining while" \
  "draining, serving 0); then: $(cat "$work/scrapes/end")"

# ---- 4. JSON log lines ---------------------------------------------------------------------
python3 - "$work/server.log" <<'PY' || fail "--log-format json"
import json, sys
lines = open(sys.argv[1]).read().splitlines()
for line in lines:
    record = json.loads(line)
    assert {"time", "level", "thread", "message"} <= record.keys(), line
assert any("metrics on" in json.loads(l)["message"] for l in lines)
print(f"metrics-test: {len(lines)} log lines, each one JSON object")
PY
say PASSED
