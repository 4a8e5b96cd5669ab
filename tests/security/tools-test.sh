#!/usr/bin/env bash
# Every client tool against a real server with mutual TLS and the example authorization
# policy (deploy/authz-policy.json), with certificates made here by scripts/make-dev-certs.sh:
#   - a plaintext client, and a TLS client without a certificate, are refused with an error
#     that says so (UNAVAILABLE and gRPC's reason);
#   - with the renderer's certificate skinserve-cli (health, backends, upload, verify,
#     stream), skinserve-load (every answer checked) and the scale-out driver (every frame
#     accounted for) work;
#   - the policy: the renderer is refused GetServerStats (PERMISSION_DENIED), the operator
#     is not.
# The Python client's TLS is tested by its own suite (client/python/tests/test_tls.py).
# usage: tools-test.sh SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD SCALEOUT-DRIVER REPOSITORY-ROOT
set -euo pipefail
if [ $# -ne 5 ]; then
  echo "usage: $0 skinserve skinserve-cli skinserve-load scaleout-driver repository-root" >&2
  exit 2
fi
server=$1 cli=$2 load=$3 driver=$4 root=$5
command -v openssl >/dev/null || { echo "tools-test: SKIPPED: no openssl"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-tls-tools.XXXXXX")
server_pid=""
cleanup() {
  local rc=$?
  if [ -n "$server_pid" ]; then
    kill -TERM "$server_pid" 2>/dev/null || true
    wait "$server_pid" 2>/dev/null || true
  fi
  if [ $rc -ne 0 ] && [ -f "$work/server.log" ]; then
    echo "--- server log, last 20 lines"
    tail -20 "$work/server.log"
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
say() { echo "tls-tools: $*"; }
fail() { echo "tls-tools: FAILED: $*" >&2; exit 1; }

bash "$root/scripts/make-dev-certs.sh" "$work/certs" operator renderer >/dev/null
c=$work/certs
"$server" --listen 127.0.0.1:0 --port-file "$work/port" --threads 1 --log-level warn \
  --backends sse,passthrough --default-backend sse \
  --tls-cert "$c/server.pem" --tls-key "$c/server.key" --tls-client-ca "$c/ca.pem" \
  --authz-policy "$root/deploy/authz-policy.json" >"$work/server.log" 2>&1 &
server_pid=$!
for _ in $(seq 600); do [ -s "$work/port" ] && break; sleep 0.1; done
[ -s "$work/port" ] || fail "the server wrote no port in 60 s"
target="127.0.0.1:$(cat "$work/port")"
renderer=(--target "$target" --tls-ca "$c/ca.pem" --tls-cert "$c/renderer.pem" --tls-key "$c/renderer.key")
operator=(--target "$target" --tls-ca "$c/ca.pem" --tls-cert "$c/operator.pem" --tls-key "$c/operator.key")
say "server on $target: mutual TLS, policy deploy/authz-policy.json"

# ---- refused: plaintext, and TLS without a client certificate --------------------------
if "$cli" --target "$target" --deadline-seconds 5 backends >"$work/plain.out" 2>&1; then
  fail "a plaintext client was served"
fi
# The client's own error and hint (gRPC's log lines, "E1126 12:00:00...", left out).
message() { grep -vE '^[EWI][0-9]{4} ' "$1" | tr '\n' ' '; }
say "plaintext client: $(message "$work/plain.out")"
grep -q "UNAVAILABLE" "$work/plain.out" || fail "the plaintext client's error does not say UNAVAILABLE"
if "$cli" --target "$target" --tls-ca "$c/ca.pem" --deadline-seconds 5 backends \
    >"$work/anonymous.out" 2>&1; then
  fail "a client without a certificate was served"
fi
say "TLS client without a certificate: $(message "$work/anonymous.out")"
grep -q "UNAVAILABLE" "$work/anonymous.out" || fail "the anonymous client's error does not say UNAVAILABLE"
grep -q -- "--tls-cert" "$work/anonymous.out" || fail "the anonymous client's hint does not name --tls-cert"
if "$cli" --target "$target" --tls-ca "$c/ca.pem" --tls-cert "$c/renderer.pem" \
    backends >"$work/half.out" 2>&1; then
  fail "--tls-cert without --tls-key was accepted"
fi
grep -q -- "--tls-key" "$work/half.out" || fail "the error does not name --tls-key: $(cat "$work/half.out")"

# ---- skinserve-cli with the renderer's certificate -------------------------------------
"$cli" "${renderer[@]}" health >/dev/null || fail "skinserve-cli health over mutual TLS"
"$cli" "${renderer[@]}" backends >"$work/backends.out" || fail "skinserve-cli backends"
"$cli" "${renderer[@]}" upload --vertices 5000 >"$work/upload.out" || fail "skinserve-cli upload"
"$cli" "${renderer[@]}" verify --vertices 3000 >"$work/verify.out" ||
  { cat "$work/verify.out"; fail "skinserve-cli verify (answers against the reference)"; }
"$cli" "${renderer[@]}" stream --vertices 5000 --frames 100 --backend sse >"$work/stream.out" ||
  { cat "$work/stream.out"; fail "skinserve-cli stream"; }
say "skinserve-cli as renderer: health, backends, upload, verify ($(grep -c ' ok' "$work/verify.out" || true) backends ok), stream: $(head -1 "$work/stream.out")"

# ---- the policy ------------------------------------------------------------------------
if "$cli" "${renderer[@]}" stats >"$work/stats-renderer.out" 2>&1; then
  fail "the renderer read GetServerStats, which the policy keeps for the operator"
fi
grep -q PERMISSION_DENIED "$work/stats-renderer.out" ||
  fail "the renderer's refusal is not PERMISSION_DENIED: $(cat "$work/stats-renderer.out")"
"$cli" "${operator[@]}" stats >"$work/stats-operator.out" || fail "the operator's stats"
say "policy: renderer stats -> $(message "$work/stats-renderer.out"); operator stats ok"

# ---- skinserve-load, every answer checked ----------------------------------------------
"$load" "${renderer[@]}" --backends sse --vertices 5000 --streams 2 --warmup 0 --duration 1 \
  --check-every 1 --json "$work/load.json" >"$work/load.out" 2>&1 ||
  { cat "$work/load.out"; fail "skinserve-load over mutual TLS"; }
python3 - "$work/load.json" <<'PY' || fail "skinserve-load's report"
import json, sys
r = json.load(open(sys.argv[1]))["results"][0]
print(f"tls-tools: skinserve-load as renderer: {r['frames']} frames, {r['checked']} checked, "
      f"{r['mismatches']} wrong, errors {r['errors']}")
sys.exit(1 if r["errors"] or r["mismatches"] or not r["checked"] else 0)
PY

# ---- the scale-out driver, every frame accounted for ------------------------------------
"$driver" "${renderer[@]}" --backend sse --vertices 5000 --streams 2 --seconds 1 \
  >"$work/driver.json" 2>"$work/driver.err" ||
  { cat "$work/driver.json" "$work/driver.err"; fail "scale-out driver over mutual TLS"; }
say "scale-out driver as renderer: $(cat "$work/driver.json")"
say "PASSED"
