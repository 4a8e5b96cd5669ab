#!/usr/bin/env bash
# What TLS costs per frame: two servers on this machine, one plaintext and one with mutual
# TLS (the deployment's mode, certificates made here), each measured in turn by
# skinserve-load --capacity (25k vertices x 2 bones, float32, 60 fps streams, p99 within a
# frame and nothing dropped; over gRPC), alternating for ROUNDS rounds so that a machine
# that slows down in between hits both. For each search it also counts the frames the
# server served and the CPU time it and the load client spent: CPU per frame, server and
# client, is TLS's cost in the same units on any machine.
#   scripts/tls-cost.sh OUT [ROUNDS (2)]
# writes OUT/capacity.txt (every search's console output, each after a "== SETUP, round N"
# line), OUT/capacity-SETUP-N.json (skinserve-load --json) and OUT/cost.csv.
# Env: SKINSERVE_BIN (folder with skinserve, skinserve-cli, skinserve-load; default the
#      build's), TLS_COST_SECONDS (measured seconds per probe, default 3).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin=${SKINSERVE_BIN:-$root/build/bin}
out=${1:?usage: tls-cost.sh OUT [ROUNDS]}
rounds=${2:-2}
seconds=${TLS_COST_SECONDS:-3}
mkdir -p "$out"
out=$(cd "$out" && pwd)
work=$(mktemp -d)
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
# shellcheck source-path=SCRIPTDIR source=lib/port-file.sh
source "$root/scripts/lib/port-file.sh"

bash "$root/scripts/make-dev-certs.sh" "$work/certs" renderer >/dev/null
c=$work/certs
declare -A port pid client
for setup in plain tls; do
  extra=()
  client[$setup]=""
  if [ "$setup" = tls ]; then
    extra=(--tls-cert "$c/server.pem" --tls-key "$c/server.key" --tls-client-ca "$c/ca.pem")
    client[$setup]="--tls-ca $c/ca.pem --tls-cert $c/renderer.pem --tls-key $c/renderer.key"
  fi
  "$bin/skinserve" --listen 127.0.0.1:0 --port-file "$work/$setup.port" --log-level warn \
    "${extra[@]}" >"$work/$setup.log" 2>&1 &
  pid[$setup]=$!
  pids+=("${pid[$setup]}")
  port[$setup]=$(wait_for_port "$work/$setup.port" "${pid[$setup]}" 120) ||
    { cat "$work/$setup.log"; exit 1; }
done

# CPU seconds (user + system) a process has used so far.
cpu_seconds() {
  awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' <(sed 's/.*) //; s/^/x x /' "/proc/$1/stat")
}
frames_served() {  # setup
  # shellcheck disable=SC2086 # client[] is a list of flags
  "$bin/skinserve-cli" --target "127.0.0.1:${port[$1]}" ${client[$1]} stats --frames-only
}

echo "set-up,round,characters held,frames served,server CPU s,server CPU us per frame,load client CPU s,load client CPU us per frame" >"$out/cost.csv"
: >"$out/capacity.txt"
for round in $(seq 1 "$rounds"); do
  for setup in plain tls; do
    echo "== $setup, round $round" | tee -a "$out/capacity.txt"
    frames_before=$(frames_served "$setup")
    cpu_before=$(cpu_seconds "${pid[$setup]}")
    # The load client's own CPU time: its rusage, read by a small parent.
    # shellcheck disable=SC2086 # client[] is a list of flags
    python3 - "$work/client-cpu" "$bin/skinserve-load" --target "127.0.0.1:${port[$setup]}" \
      ${client[$setup]} --capacity --backends simd-openmp --capacity-max-streams 256 \
      --duration "$seconds" --warmup 0.5 --check-every 20 \
      --json "$out/capacity-$setup-$round.json" <<'PY' | tee -a "$out/capacity.txt"
import resource, subprocess, sys
code = subprocess.run(sys.argv[2:]).returncode
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
open(sys.argv[1], "w").write(f"{usage.ru_utime + usage.ru_stime}\n")
sys.exit(code)
PY
    cpu_after=$(cpu_seconds "${pid[$setup]}")
    frames=$(($(frames_served "$setup") - frames_before))
    held=$(sed -n 's/^capacity: \([0-9]*\) characters.*/\1/p' "$out/capacity.txt" | tail -1)
    python3 - "$setup" "$round" "$held" "$frames" "$cpu_before" "$cpu_after" \
      "$(cat "$work/client-cpu")" >>"$out/cost.csv" <<'PY'
import sys
setup, rnd, held, frames = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
server = float(sys.argv[6]) - float(sys.argv[5])
client = float(sys.argv[7])
print(f"{'mutual TLS' if setup == 'tls' else 'plaintext'},{rnd},{held},{frames},{server:.1f},"
      f"{1e6 * server / frames:.0f},{client:.1f},{1e6 * client / frames:.0f}")
PY
    echo | tee -a "$out/capacity.txt"
  done
done
cat "$out/cost.csv"
