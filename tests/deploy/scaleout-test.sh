#!/usr/bin/env bash
# Scale-out on one machine: three skinserve replicas on free loopback ports behind one
# client-side round_robin target, ipv4:127.0.0.1:P1,127.0.0.1:P2,127.0.0.1:P3.
#
#   balance  skinserve-load on every CPU and OpenCL backend with every answer checked
#            against the float64 reference: no error, no mismatch, and every replica
#            served frames (each server's own stats, skinserve-cli stats).
#   fault    one replica is SIGKILLed mid-run. Its streams fail with UNAVAILABLE, the
#            client library moves them to the others (re-uploading the mesh where it gets
#            NOT_FOUND) and the run finishes. skinserve-load must report no mismatch and
#            only UNAVAILABLE errors; scaleout-driver (the client library's StreamFrames,
#            every answer checked) must account for every frame:
#            sent = answered + reported failed, none wrong.
#   freeze   as fault, but the replica is frozen (SIGSTOP) instead: it vanishes without a
#            FIN or a reset, as a hung node or a dropped link does, and nothing answers
#            its connections. The clients (keepalive every 2 s, 1 s to answer) must give
#            its streams up within that bound, report their frames in flight failed
#            (UNAVAILABLE) and carry on on the other two; every frame accounted for, the
#            run no longer than planned plus the bound.
#   grow     a scale-up seen by clients that resolve a DNS name, as behind a headless
#            Service: the name resolves (native resolver, /etc/hosts in a private mount
#            namespace) to two replicas on 127.0.0.1 and 127.0.0.2, one port; mid-run a
#            third, on 127.0.0.3, joins the name. The servers' maximum
#            connection age makes the clients reconnect and so re-resolve: the third
#            replica must receive frames before the run ends. scaleout-driver streams
#            clips (one StreamSkin call each), every answer checked and every frame
#            accounted for. Needs root (unshare -m, mount --bind); else skipped.
#
# The servers are always stopped. Bounded: each run is a few seconds; the whole test well
# under two minutes.
# usage: scaleout-test.sh balance|fault|freeze|grow SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD
#                        SCALEOUT-DRIVER
set -euo pipefail

if [ $# -ne 5 ]; then
  echo "usage: $0 balance|fault|freeze|grow skinserve skinserve-cli skinserve-load scaleout-driver" >&2
  exit 2
fi
mode=$1 server=$2 cli=$3 load=$4 driver=$5
case "$mode" in balance | fault | freeze | grow) ;; *) echo "unknown mode $mode" >&2; exit 2 ;; esac
if [ "$mode" = grow ] && [ -z "${SKINSERVE_SCALEOUT_NAMESPACE:-}" ]; then
  # A private mount namespace, so the test's /etc/hosts is seen by this test alone.
  if [ "$(id -u)" -ne 0 ] || ! command -v unshare >/dev/null; then
    echo "scaleout[grow]: SKIPPED: needs root and unshare (a private /etc/hosts)"
    exit 77
  fi
  SKINSERVE_SCALEOUT_NAMESPACE=1 exec unshare --mount --propagation private bash "$0" "$@"
fi
replicas=3
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-scaleout.XXXXXX")
pids=()
ports=()

say() { echo "scaleout[$mode]: $*"; }
fail() { echo "scaleout[$mode]: FAILED: $*" >&2; exit 1; }

cleanup() {
  local rc=$?
  for pid in "${pids[@]}"; do kill -CONT "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  if [ $rc -ne 0 ]; then
    for i in "${!ports[@]}"; do
      echo "--- replica $i (127.0.0.1:${ports[$i]}) log, last 15 lines"
      tail -15 "$work/server$i.log" 2>/dev/null || true
    done
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

if [ "$mode" = grow ]; then
  name=skinserve.scaleout.test
  port=$(free_port)
  hosts="$work/hosts"
  printf '127.0.0.1 localhost\n127.0.0.1 %s\n127.0.0.2 %s\n' "$name" "$name" >"$hosts"
  mount --bind "$hosts" /etc/hosts
  # One compute thread each. Connections age out after 2 s (+-10%): each GOAWAY makes the
  # client re-resolve; the 10 s grace is longer than any clip of frames here.
  start_replica() {  # index, address
    "$server" --listen "$2:$port" --threads 1 --max-connection-age-seconds 2 \
      --max-connection-age-grace-seconds 10 >"$work/server$1.log" 2>&1 &
    pids+=($!)
    ports+=("$2:$port")
    "$cli" --target "$2:$port" health --wait 60 >/dev/null ||
      fail "replica $1 ($2:$port) not SERVING after 60 s"
  }
  seconds_since() { python3 -c "import sys, time; print(f'{time.time() - float(sys.argv[1]):.1f}')" "$1"; }
  start_replica 0 127.0.0.1
  start_replica 1 127.0.0.2
  # The third starts now but joins the name only mid-run, as a pod joins a headless
  # Service's DNS once ready: what is timed is the clients finding it, not its start-up.
  start_replica 2 127.0.0.3
  run_seconds=45 grow_after=5
  target="dns:///$name:$port"
  say "3 replicas SERVING, 2 of them as $name; scaleout-driver (sse, 6 clients, clips of 30 frames," \
    "${run_seconds} s) on $target with the native resolver"
  started=$(date +%s.%N)
  GRPC_DNS_RESOLVER=native timeout 120 "$driver" --target "$target" --backend sse \
    --vertices 20000 --streams 6 --window 4 --seconds "$run_seconds" --clip-frames 30 \
    >"$work/driver.json" 2>"$work/driver.err" &
  driver_pid=$!
  sleep "$grow_after"
  [ "$("$cli" --target "127.0.0.3:$port" stats --frames-only)" -eq 0 ] ||
    fail "replica 2 served frames before it joined $name"
  # Appended in place: the bind mount holds this inode.
  printf '127.0.0.3 %s\n' "$name" >>"$hosts"
  added=$(date +%s.%N)
  say "replica 2 (127.0.0.3:$port, SERVING, no frames yet) added to $name" \
    "$(seconds_since "$started") s into the run"
  first_seen=""
  while kill -0 "$driver_pid" 2>/dev/null; do
    n=$("$cli" --target "127.0.0.3:$port" stats --frames-only 2>/dev/null || echo 0)
    if [ -z "$first_seen" ] && [ "$n" -gt 0 ]; then
      first_seen=$(date +%s.%N)
      say "replica 2 served its first frames $(seconds_since "$added") s after it was added" \
        "($(seconds_since "$started") s into the run)"
    fi
    sleep 0.5
  done
  driver_rc=0
  wait "$driver_pid" || driver_rc=$?
  echo "driver: $(cat "$work/driver.json")"
  [ -s "$work/driver.err" ] && sed 's/^/driver stderr: /' "$work/driver.err" | tail -5
  counts=()
  for i in 0 1 2; do counts+=("$("$cli" --target "${ports[$i]}" stats --frames-only)"); done
  say "frames per replica at the end: ${counts[*]}"
  python3 - "$work/driver.json" "$driver_rc" <<'EOF' || fail "accounting"
import json, sys
drv, rc = json.loads(open(sys.argv[1]).read()), int(sys.argv[2])
problems = []
if drv["sent"] != drv["answered"] + drv["failed"] or not drv["balanced"] or not drv["sink_agrees"]:
    problems.append(f"frames lost: sent {drv['sent']}, answered {drv['answered']}, failed {drv['failed']}")
if drv["wrong"] or drv["failed"] or drv["answered"] == 0 or rc != 0:
    problems.append(f"wrong {drv['wrong']}, failed {drv['failed_by_code']}, exit {rc}")
print(f"accounting: sent {drv['sent']} = answered {drv['answered']} (all correct) + failed "
      f"{drv['failed']} in {drv['clips']} clips; reconnects {drv['reconnects']}, "
      f"re-uploads {drv['reuploads']}")
for p in problems:
    print("problem:", p)
sys.exit(1 if problems else 0)
EOF
  [ -n "$first_seen" ] && [ "${counts[2]}" -gt 0 ] ||
    fail "replica 2, added after ${grow_after} s, served no frame in a ${run_seconds} s run"
  say "PASSED: the replica added mid-run served ${counts[2]} of" \
    "$((counts[0] + counts[1] + counts[2])) frames"
  exit 0
fi

# ---- three replicas --------------------------------------------------------------------
for i in $(seq 0 $((replicas - 1))); do
  port=$(free_port)
  ports+=("$port")
  # One compute thread each: three replicas and the clients share this machine's cores.
  "$server" --listen "127.0.0.1:$port" --threads 1 --log-level info >"$work/server$i.log" 2>&1 &
  pids+=($!)
done
for i in "${!ports[@]}"; do
  "$cli" --target "127.0.0.1:${ports[$i]}" health --wait 60 >/dev/null ||
    fail "replica $i (127.0.0.1:${ports[$i]}) not SERVING after 60 s"
done
target="ipv4:$(printf '127.0.0.1:%s,' "${ports[@]}")"
target=${target%,}
say "replicas SERVING; target $target"

frames_of() { "$cli" --target "127.0.0.1:$1" stats --frames-only; }

if [ "$mode" = balance ]; then
  # ---- every replica serves, every answer right -----------------------------------------
  backends=serial,sse,sse-openmp,opencl,opencl-zerocopy
  say "skinserve-load: $backends, 6 streams, 2 s each, every answer checked"
  timeout 120 "$load" --target "$target" --backends "$backends" --vertices 20000 \
    --streams 6 --window 4 --warmup 0 --duration 2 --check-every 1 \
    --json "$work/load.json" >"$work/load.out" 2>&1 || {
    cat "$work/load.out"
    fail "skinserve-load reported errors or mismatches"
  }
  cat "$work/load.out"
  python3 - "$work/load.json" <<'EOF' || fail "load report"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
bad = [r["backend"] for r in results
       if r["errors"] or r["mismatches"] or r["checked"] == 0 or r["frames"] == 0]
print("load: " + ", ".join(f"{r['backend']} {r['frames']} frames, {r['checked']} checked, "
                           f"{r['mismatches']} wrong" for r in results))
sys.exit(1 if bad else 0)
EOF
  total=0
  for i in "${!ports[@]}"; do
    n=$(frames_of "${ports[$i]}")
    say "replica $i (127.0.0.1:${ports[$i]}): $n frames"
    [ "$n" -gt 0 ] || fail "replica $i served no frames: round_robin did not spread the streams"
    total=$((total + n))
  done
  say "PASSED: $total frames over $replicas replicas, all correct"
  exit 0
fi

# ---- fault: SIGKILL one replica mid-run; freeze: SIGSTOP it -------------------------------
run_seconds=8
kill_after=3
signal=KILL
client_options=()
expected=UNAVAILABLE
if [ "$mode" = freeze ]; then
  # A frozen replica answers nothing; keepalive (a ping every 2 s, 1 s to answer) finds it.
  signal=STOP
  client_options=(--keepalive-seconds 2 --keepalive-timeout-seconds 1)
  bound=3
fi
say "skinserve-load (sse, 6 streams, ${run_seconds} s) and scaleout-driver (sse, 6 streams," \
  "${run_seconds} s) at once; the busiest replica gets SIG$signal after ${kill_after} s"
started=$(date +%s.%N)
timeout 120 "$load" --target "$target" "${client_options[@]}" --backends sse --vertices 20000 \
  --streams 6 --window 4 --warmup 0 --duration "$run_seconds" --check-every 1 \
  --json "$work/load.json" >"$work/load.out" 2>&1 &
load_pid=$!
timeout 120 "$driver" --target "$target" "${client_options[@]}" --backend sse --vertices 20000 \
  --streams 6 --window 4 --seconds "$run_seconds" >"$work/driver.json" 2>"$work/driver.err" &
driver_pid=$!

sleep "$kill_after"
before=()
for i in "${!ports[@]}"; do before+=("$(frames_of "${ports[$i]}" || echo 0)"); done
say "before the fault: frames per replica: ${before[*]}"
# The busiest replica: it certainly holds open streams when it dies. (That streams spread
# over every replica is scaleout.balance's check; 12 random placements can miss one.)
victim=0
for i in "${!ports[@]}"; do
  [ "${before[$i]}" -gt "${before[$victim]}" ] && victim=$i
done
[ "${before[$victim]}" -gt 0 ] || fail "no replica served frames in the first ${kill_after} s"
kill -"$signal" "${pids[$victim]}"
[ "$signal" = KILL ] && { wait "${pids[$victim]}" 2>/dev/null || true; }
say "replica $victim (127.0.0.1:${ports[$victim]}) got SIG$signal"

load_rc=0
wait "$load_pid" || load_rc=$?
driver_rc=0
wait "$driver_pid" || driver_rc=$?
took=$(python3 -c "import sys, time; print(f'{time.time() - float(sys.argv[1]):.1f}')" "$started")
say "both clients finished ${took} s after they started (a ${run_seconds} s run)"
if [ "$mode" = freeze ]; then
  # Each stream on the frozen replica is given up within the keepalive bound; the clients'
  # runs end on time (a stream still waiting on it would hold its client past the end).
  python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) <= float(sys.argv[2]) else 1)" \
    "$took" "$((run_seconds + bound + 3))" ||
    fail "the clients took ${took} s, more than the run (${run_seconds} s) + the keepalive bound (${bound} s) + 3 s"
fi
cat "$work/load.out"
echo "driver: $(cat "$work/driver.json")"
[ -s "$work/driver.err" ] && sed 's/^/driver stderr: /' "$work/driver.err" | tail -5
if [ "$load_rc" -eq 124 ] || [ "$driver_rc" -eq 124 ]; then
  fail "a client did not finish in 120 s"
fi

after=()
for i in "${!ports[@]}"; do
  if [ "$i" -eq "$victim" ]; then after+=("SIG$signal"); continue; fi
  after+=("$(frames_of "${ports[$i]}")")
done
say "after the run: frames per replica: ${after[*]} (replica $victim served ${before[$victim]}+" \
  "before SIG$signal)"

python3 - "$work/load.json" "$work/driver.json" "$load_rc" "$driver_rc" <<'EOF' || fail "accounting"
import json, sys
load = json.load(open(sys.argv[1]))["results"][0]
drv = json.loads(open(sys.argv[2]).read())
load_rc, driver_rc = int(sys.argv[3]), int(sys.argv[4])
problems = []
# skinserve-load: every checked answer right; the only errors are the killed replica's.
if load["mismatches"]:
    problems.append(f"skinserve-load: {load['mismatches']} wrong answers")
if load["checked"] == 0 or load["frames"] == 0:
    problems.append("skinserve-load: no answer checked")
if set(load["errors"]) - {"UNAVAILABLE"}:
    problems.append(f"skinserve-load: errors other than UNAVAILABLE: {load['errors']}")
# skinserve-load exits 1 on any error: fine here, it must be because of UNAVAILABLE only.
if load_rc not in (0, 1):
    problems.append(f"skinserve-load exited {load_rc}")
# scaleout-driver: every frame accounted for.
if drv["sent"] != drv["answered"] + drv["failed"]:
    problems.append(f"driver: sent {drv['sent']} != answered {drv['answered']} + failed "
                    f"{drv['failed']}: frames lost silently")
if not drv["balanced"] or not drv["sink_agrees"]:
    problems.append("driver: a stream's frames do not add up")
if drv["wrong"]:
    problems.append(f"driver: {drv['wrong']} wrong answers")
if set(drv["failed_by_code"]) - {"UNAVAILABLE"}:
    problems.append(f"driver: frames failed other than UNAVAILABLE: {drv['failed_by_code']}")
if drv["failed"] == 0 and sum(load["errors"].values()) == 0:
    problems.append("no client saw the replica go: was it serving any stream?")
if drv["answered"] == 0:
    problems.append("driver: nothing answered")
if driver_rc != 0 and not problems:
    problems.append(f"driver exited {driver_rc}")
print(f"accounting: driver sent {drv['sent']} = answered {drv['answered']} (all correct) + "
      f"failed {drv['failed']} {drv['failed_by_code']}; reconnects {drv['reconnects']}, "
      f"re-uploads {drv['reuploads']}; skinserve-load {load['frames']} frames, "
      f"{load['checked']} checked, {load['mismatches']} wrong, errors {load['errors']}")
for p in problems:
    print("problem:", p)
sys.exit(1 if problems else 0)
EOF
for i in "${!ports[@]}"; do
  [ "$i" -eq "$victim" ] && continue
  [ "${after[$i]}" -gt "${before[$i]}" ] ||
    fail "survivor replica $i served nothing after the kill"
done
say "PASSED"
