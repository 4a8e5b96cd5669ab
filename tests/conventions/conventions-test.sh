#!/usr/bin/env bash
# The command-line conventions of issue 30 on real servers and real programs:
#   1. --version: every program prints "<name> <version>", the same version for all;
#   2. skinserve --config: a file's threads and max-vertices show in GetServerStats and in
#      an upload refused; a flag overrides the file; the environment alone still applies;
#      SKINSERVE_CONFIG names the file (a missing one refused);
#      the file and the environment disagreeing is a start-up error naming both; a bad
#      value and an unknown key are start-up errors naming the file's line;
#   3. skinserve-load --config: the file's streams, frames and backends are in its JSON
#      report; a flag overrides the file; a bad file names its line;
#   4. skinserve-cli stats --json and backends --json parse, and match the server (the
#      frames the load client sent, the compute threads, the text listing);
#   5. animate: a progress line on a terminal (script(1)), none in a pipe.
# usage: conventions-test.sh SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD GLTF-DIR [TOOL...]
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"
if [ $# -lt 4 ]; then
  echo "usage: $0 SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD GLTF-DIR [TOOL...]" >&2
  exit 2
fi
server=$1 cli=$2 load=$3 assets=$4
shift 4
tools=("$@")
for tool in python3 script; do
  command -v "$tool" >/dev/null || { echo "conventions-test: SKIPPED: $tool missing"; exit 77; }
done
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-conventions.XXXXXX")
pids=()
say() { echo "conventions-test: $*"; }
fail() { echo "conventions-test: FAILED: $*" >&2; exit 1; }
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
# Starts a server with "$@" and sets $port; its log is $work/server-$1.log.
start_server() {
  local name=$1
  shift
  rm -f "$work/port"
  "$server" --listen 127.0.0.1:0 --port-file "$work/port" --log-level warn "$@" \
    >"$work/server-$name.log" 2>&1 &
  pids+=("$!")
  port=$(wait_for_port "$work/port" "$!" 60) || fail "server ($name) not serving"
}
stop_servers() {
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; done
  pids=()
}
# The value of a field of the JSON object on stdin, e.g. json_field compute_threads.
json_field() { python3 -c 'import json, sys; print(json.load(sys.stdin)[sys.argv[1]])' "$1"; }
# Runs "$@" expecting a start-up error that mentions every pattern in $expect (an array).
expect_refusal() {
  local log=$work/refusal.log
  if timeout 30 "$@" >"$log" 2>&1; then fail "accepted: $* ($(cat "$log"))"; fi
  for pattern in "${expect[@]}"; do
    grep -qF -- "$pattern" "$log" || fail "'$*' refused without naming '$pattern': $(cat "$log")"
  done
  say "refused as expected: $(head -1 "$log")"
}

# ---- 1. --version ------------------------------------------------------------------------------
version=
for program in "$server" "$cli" "$load" "${tools[@]}"; do
  name=$(basename "$program")
  line=$("$program" --version) || fail "$name --version failed"
  case "$line" in "$name "[0-9]*) ;; *) fail "$name --version: '$line'" ;; esac
  this=${line#"$name "}
  [ -z "$version" ] || [ "$this" = "$version" ] || fail "$name says '$this', others '$version'"
  version=$this
done
say "every program: $version"

# ---- 2. skinserve --config ---------------------------------------------------------------------
cat >"$work/server.toml" <<'TOML'
# a server configuration (TOML)
threads = 3
max-vertices = 5000
TOML
start_server file --config "$work/server.toml"
threads=$("$cli" --target "127.0.0.1:$port" stats --json | json_field compute_threads)
[ "$threads" = 3 ] || fail "--config threads = 3: the server runs $threads compute threads"
"$cli" --target "127.0.0.1:$port" upload --vertices 4000 >"$work/upload-ok.log" 2>&1 ||
  fail "4000 vertices refused under max-vertices = 5000"
if "$cli" --target "127.0.0.1:$port" upload --vertices 6000 >"$work/upload-big.log" 2>&1; then
  fail "6000 vertices accepted under max-vertices = 5000"
fi
grep -q 5000 "$work/upload-big.log" || fail "the refusal does not name the limit 5000"
stop_servers
say "config file: 3 compute threads, 6000 vertices refused (max 5000)"

start_server flag --config "$work/server.toml" --threads 2
threads=$("$cli" --target "127.0.0.1:$port" stats --json | json_field compute_threads)
[ "$threads" = 2 ] || fail "--threads 2 over the file's 3: the server runs $threads"
stop_servers
SKINSERVE_THREADS=2 start_server flag-over-env --config "$work/server.toml" --threads 1
threads=$("$cli" --target "127.0.0.1:$port" stats --json | json_field compute_threads)
[ "$threads" = 1 ] || fail "--threads 1 over the file's 3 and the environment's 2: $threads"
stop_servers
printf 'max-vertices = 5000\n' >"$work/no-threads.toml"
SKINSERVE_THREADS=2 start_server env --config "$work/no-threads.toml"
threads=$("$cli" --target "127.0.0.1:$port" stats --json | json_field compute_threads)
[ "$threads" = 2 ] || fail "SKINSERVE_THREADS=2, the file silent on threads: the server runs $threads"
stop_servers
SKINSERVE_THREADS=3 start_server env-agrees --config "$work/server.toml"
stop_servers
SKINSERVE_CONFIG=$work/server.toml start_server env-file
threads=$("$cli" --target "127.0.0.1:$port" stats --json | json_field compute_threads)
[ "$threads" = 3 ] || fail "SKINSERVE_CONFIG=server.toml (threads = 3): the server runs $threads"
stop_servers
say "flag over file and environment; environment where the file is silent; agreeing ones start;"
say "SKINSERVE_CONFIG names the file"

expect=(SKINSERVE_THREADS=4 "$work/server.toml line 2" threads)
SKINSERVE_THREADS=4 expect_refusal "$server" --listen 127.0.0.1:0 --config "$work/server.toml"
printf '# bad value\nmax-vertices = 5000\nthreads = many\n' >"$work/bad-value.toml"
expect=("line 3" "threads = many")
expect_refusal "$server" --listen 127.0.0.1:0 --config "$work/bad-value.toml"
printf 'threads = 1\n\nno-such-option = 1\n' >"$work/bad-key.ini"
expect=("line 3" "no-such-option")
expect_refusal "$server" --listen 127.0.0.1:0 --config "$work/bad-key.ini"
expect=("no-such-file.toml")
expect_refusal "$server" --listen 127.0.0.1:0 --config "$work/no-such-file.toml"
SKINSERVE_CONFIG=$work/no-such-file.toml expect_refusal "$server" --listen 127.0.0.1:0

# ---- 3. skinserve-load --config, 4. --json against the server -------------------------------------
start_server load --threads 2
target=127.0.0.1:$port
cat >"$work/load.ini" <<INI
; a load run (INI)
target = $target
backends = serial
vertices = 2000
streams = 2
frames = 7
warmup = 0
check-every = 1
INI
"$load" --config "$work/load.ini" --json "$work/load-file.json" >"$work/load-file.log" 2>&1 ||
  fail "skinserve-load --config"
"$load" --config "$work/load.ini" --streams 1 --json "$work/load-flag.json" >"$work/load-flag.log" 2>&1 ||
  fail "skinserve-load --config --streams 1"
python3 - "$work/load-file.json" "$work/load-flag.json" <<'PY' || fail "load reports"
import json, sys
file, flag = (json.load(open(p))["results"] for p in sys.argv[1:3])
assert [r["backend"] for r in file] == ["serial"], file
f = file[0]
assert (f["streams"], f["frames"], f["vertices"], f["mismatches"]) == (2, 14, 2000, 0), f
assert f["checked"] == 14, f
g = flag[0]
assert (g["streams"], g["frames"], g["vertices"]) == (1, 7, 2000), g
PY
say "load client: the file's 2 streams x 7 frames of 2000 vertices, --streams 1 over it"
printf 'target = %s\nstreams = two\n' "$target" >"$work/bad-load.ini"
expect=("line 2" "streams = two")
expect_refusal "$load" --config "$work/bad-load.ini"

"$cli" --target "$target" stats --json >"$work/stats.json" || fail "stats --json"
"$cli" --target "$target" backends --json >"$work/backends.json" || fail "backends --json"
"$cli" --target "$target" backends >"$work/backends.txt" || fail "backends"
python3 - "$work/stats.json" "$work/backends.json" "$work/backends.txt" <<'PY' || fail "--json"
import json, sys
stats, backends = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
text = open(sys.argv[3]).read().splitlines()
# The load runs sent 2 x 7 + 1 x 7 frames, all to serial; nothing else ran on this server.
frames = {b["id"]: int(b["frames"]) for b in stats["backends"]}
assert frames.get("serial") == 21, frames
assert sum(frames.values()) == 21, frames
assert stats["compute_threads"] == 2, stats["compute_threads"]
assert int(stats["meshes"]) >= 1, stats
# backends --json lists what the table lists, with the same default.
ids = [b["id"] for b in backends["backends"]]
table = [line.split()[0] for line in text[1:-1]]
assert ids == table, (ids, table)
assert text[-1] == "default: " + backends["default_backend"], (text[-1], backends["default_backend"])
assert all(isinstance(b["available"], bool) for b in backends["backends"])
# The table's encodes column is BackendInfo.encoded_outputs ("-": none).
for b, line in zip(backends["backends"], text[1:-1]):
    names = [e.removeprefix("ENCODING_").lower() for e in b.get("encoded_outputs", [])]
    assert line.split()[5] == (",".join(names) or "-"), (b, line)
PY
say "stats --json: 21 frames on serial, 2 compute threads; backends --json = the table"

# ---- 5. animate's progress line --------------------------------------------------------------------
"$cli" --target "$target" animate "$assets/RiggedSimple.glb" --seconds 1 --fps 6 \
  --out "$work/piped" >"$work/piped.out" 2>"$work/piped.err" || fail "animate in a pipe"
if grep -q $'\r' "$work/piped.out" "$work/piped.err" || grep -q 'animate: ' "$work/piped.err"; then
  fail "animate drew progress into a pipe: $(cat -A "$work/piped.err")"
fi
script -qec "'$cli' --target '$target' animate '$assets/RiggedSimple.glb' --seconds 1 --fps 6 --out '$work/tty'" \
  /dev/null >"$work/tty.log" 2>&1 || fail "animate on a terminal: $(cat "$work/tty.log")"
grep -q $'\ranimate: 6/6 frames (100%), [0-9.]* frames/s' "$work/tty.log" ||
  fail "no progress line on a terminal: $(cat -A "$work/tty.log")"
say "animate: a progress line on a terminal, nothing in a pipe"
stop_servers
say "PASSED"
