#!/usr/bin/env bash
# Smoke test of the container image, for real, with podman:
#   1. builds deploy/Dockerfile (making the local Debian base image first when missing) on
#      that base image pinned by its digest,
#   2. starts the server container (detached, host network, on a free loopback port) with
#      mutual TLS on TCP (certificates made here, mounted read-only) and a CPU and memory
#      limit, which it must read from its cgroup,
#   3. waits for SERVING through the image's own HEALTHCHECK (grpc.health.v1, over the
#      plaintext Unix socket),
#   4. runs the image's load client against it on every backend with correctness checks,
#      over mutual TLS (and checks a plaintext client is refused),
#   5. runs the load client as a same-host client in a second container: the two share a
#      memory-backed volume (the server's --shm-dir and its Unix socket), gRPC goes over
#      the socket and every frame is written into the client's shared-memory regions,
#      then the same over the server's frame socket (--frame-socket, without gRPC),
#   6. sends SIGTERM during a load run and checks the server drains and exits 0.
# The containers (and the PoCL cache volume) are always removed, whatever happens.
#
# Exits 77 (ctest's skip code) with the reason when podman, runc or debootstrap are
# missing and cannot be installed (not root), when podman cannot run a container here,
# or when SKINSERVE_SKIP_DEPLOY_SMOKE=1.
#
# Env: SKINSERVE_IMAGE (default skinserve:<project version>),
#      SKINSERVE_SMOKE_NO_BUILD=1 (use the existing image, do not build),
#      SKINSERVE_SMOKE_DURATION (seconds of load per backend, default 2).
# usage: deploy/smoke-test.sh
set -euo pipefail

SKIP=77
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
version=$(sed -n 's/^project(skinserve VERSION \([0-9.]*\).*/\1/p' "$root/CMakeLists.txt")
image="${SKINSERVE_IMAGE:-skinserve:$version}"
duration="${SKINSERVE_SMOKE_DURATION:-2}"
name="skinserve-smoke-$$"
load_name="skinserve-smoke-load-$$"
volume="skinserve-smoke-pocl-$$"
run_volume="skinserve-smoke-run-$$"  # tmpfs: the regions and the socket
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-smoke.XXXXXX")
trap 'rm -rf "$work"' EXIT  # replaced by the full clean-up once podman is in play

say() { echo "smoke: $*"; }
skip() { echo "smoke: SKIPPED: $*"; exit "$SKIP"; }
fail() { echo "smoke: FAILED: $*" >&2; exit 1; }

if [ "${SKINSERVE_SKIP_DEPLOY_SMOKE:-0}" = 1 ]; then
  skip "SKINSERVE_SKIP_DEPLOY_SMOKE=1"
fi

# ---- tools: podman, runc, debootstrap (installed here when root, as CI is) -------------
missing=()
for tool in podman runc debootstrap python3; do
  command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    say "installing ${missing[*]} (Debian packages)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >"$work/apt.log" 2>&1 || {
      apt-get update -qq >>"$work/apt.log" 2>&1 &&
        apt-get install -y -qq --no-install-recommends "${missing[@]}" >>"$work/apt.log" 2>&1
    } || { tail -20 "$work/apt.log"; skip "could not install ${missing[*]} with apt-get"; }
  else
    skip "${missing[*]} not installed and not root to install them" \
      "(apt-get install podman runc debootstrap)"
  fi
fi
# Rootful podman only: rootless needs subuid ranges and user namespaces this test does not
# set up.
[ "$(id -u)" -eq 0 ] || skip "rootful podman needed (run as root)"

podman_run() {
  # runc: this kernel's cgroup mode defeats crun. ulimits: under the machine's hard limits.
  podman --runtime runc run --network host \
    --ulimit nofile=1024:1024 --ulimit nproc=1024:1024 "$@"
}

cleanup() {
  local rc=$?
  podman rm -f -t 0 "$load_name" >/dev/null 2>&1 || true
  if podman container exists "$name" 2>/dev/null; then
    if [ $rc -ne 0 ]; then
      echo "smoke: server container log (last 40 lines):"
      podman logs "$name" 2>&1 | tail -40 | sed 's/^/  | /'
    fi
    podman rm -f -t 0 "$name" >/dev/null 2>&1 || true
  fi
  podman volume rm -f "$volume" "$run_volume" >/dev/null 2>&1 || true
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

podman info >"$work/podman-info.txt" 2>&1 || {
  tail -5 "$work/podman-info.txt"
  skip "podman does not work here (podman info failed)"
}

# Leftovers of an earlier run that was killed before it could clean up (e.g. by a ctest
# timeout): this test's own names, whose process is gone.
for leftover in $(podman ps -a --format '{{.Names}}' | grep -E '^skinserve-smoke-(load-)?[0-9]+$' || true); do
  kill -0 "${leftover##*-}" 2>/dev/null || podman rm -f -t 0 "$leftover" >/dev/null 2>&1 || true
done
for leftover in $(podman volume ls --format '{{.Name}}' | grep -E '^skinserve-smoke-(pocl|run)-[0-9]+$' || true); do
  kill -0 "${leftover##*-}" 2>/dev/null || podman volume rm -f "$leftover" >/dev/null 2>&1 || true
done

# ---- base image, then can podman run a container at all? -------------------------------
bash "$root/deploy/make-base-image.sh"
if ! podman_run --rm docker.io/library/debian:bookworm-slim true >"$work/run.log" 2>&1; then
  tail -5 "$work/run.log"
  skip "podman cannot run a container on this machine (see the error above)"
fi

# ---- build -----------------------------------------------------------------------------
if [ "${SKINSERVE_SMOKE_NO_BUILD:-0}" = 1 ] && podman image exists "$image"; then
  say "SKINSERVE_SMOKE_NO_BUILD=1: using the existing $image"
else
  say "building $image from deploy/Dockerfile (compiles the three binaries, from the host build's compiler cache when there is one)"
  start=$(date +%s)
  # The Dockerfile pins Docker Hub's image by digest; here the local one, by its own digest.
  base_digest=$(podman image inspect --format '{{.Digest}}' docker.io/library/debian:bookworm-slim)
  say "base image docker.io/library/debian@$base_digest (the local bookworm-slim)"
  # The host build's compiler cache (scripts/build.sh ran just before, in test.sh): the
  # image's build reuses its objects instead of compiling the project a second time.
  cache_mount=()
  if command -v ccache >/dev/null 2>&1; then
    cache_dir=$(ccache --get-config cache_dir)
    mkdir -p "$cache_dir"
    cache_mount=(--volume "$cache_dir:/ccache")
    say "compiler cache $cache_dir mounted at /ccache"
  fi
  if ! podman build --pull=never --isolation chroot --network host --format docker \
      --build-arg VERSION="$version" --build-arg BASE_IMAGE="docker.io/library/debian@$base_digest" \
      "${cache_mount[@]}" -f "$root/deploy/Dockerfile" -t "$image" "$root" \
      >"$work/build.log" 2>&1; then
    tail -60 "$work/build.log"
    fail "podman build failed (last lines above)"
  fi
  grep -E '^STEP [0-9]+/[0-9]+: (FROM|RUN)' "$work/build.log" | cut -c1-110 | sed 's/^/  /' || true
  say "built $image in $(($(date +%s) - start)) s"
fi

label=$(podman image inspect --format '{{index .Labels "org.opencontainers.image.version"}}' "$image")
[ "$label" = "$version" ] || fail "image label org.opencontainers.image.version is '$label', not $version"
user=$(podman image inspect --format '{{.User}}' "$image")
case "$user" in "" | 0 | 0:* | root | root:*) fail "image runs as root (USER '$user')" ;; esac
podman image inspect --format '{{.HealthCheck}}' "$image" | grep -q skinserve-cli ||
  podman image inspect --format '{{json .Config}}' "$image" | grep -q skinserve-cli ||
  fail "image has no HEALTHCHECK using skinserve-cli"
size=$(podman image inspect --format '{{.Size}}' "$image")
say "image $image: version $label, user $user, size $((size / 1000000)) MB"

# No debugging tools in the runtime image.
for tool in clinfo gdb strace curl; do
  if podman_run --rm --no-healthcheck --entrypoint sh "$image" -c "command -v $tool" >/dev/null 2>&1; then
    fail "the runtime image has $tool"
  fi
done

# ---- run -------------------------------------------------------------------------------
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# Certificates for mutual TLS, readable by the image's user (10001): test keys only.
bash "$root/scripts/make-dev-certs.sh" "$work/certs" renderer >/dev/null
chmod 0755 "$work/certs" && chmod 0644 "$work/certs"/*
tls_mount=(-v "$work/certs:/etc/skinserve/tls:ro")
client_tls=(--tls-ca /etc/skinserve/tls/ca.pem --tls-cert /etc/skinserve/tls/renderer.pem
  --tls-key /etc/skinserve/tls/renderer.key)
drain=10
say "starting $name on 127.0.0.1:$port (mutual TLS) and unix:/run/skinserve/grpc.sock (read-only" \
  "root, a PoCL cache volume, a tmpfs volume for same-host clients, 1 CPU and 2 GiB, as in k8s/)"
podman volume create --opt type=tmpfs --opt device=tmpfs --opt o=uid=10001,gid=10001,mode=0770 \
  "$run_volume" >/dev/null
# Without systemd podman cannot put the HEALTHCHECK on a timer and says so on stderr (kept
# aside, shown on failure); this test runs the check itself with `podman healthcheck run`.
podman_run -d --name "$name" --cpus 1 --memory 2g \
  --read-only --mount "type=volume,source=$volume,destination=/var/cache/pocl" \
  --mount "type=volume,source=$run_volume,destination=/run/skinserve" "${tls_mount[@]}" \
  -e SKINSERVE_LISTEN="127.0.0.1:$port,unix:/run/skinserve/grpc.sock" \
  -e SKINSERVE_TLS_CERT=/etc/skinserve/tls/server.pem -e SKINSERVE_TLS_KEY=/etc/skinserve/tls/server.key \
  -e SKINSERVE_TLS_CLIENT_CA=/etc/skinserve/tls/ca.pem \
  -e SKINSERVE_SHM_DIR=/run/skinserve -e SKINSERVE_DRAIN_SECONDS="$drain" \
  -e SKINSERVE_FRAME_SOCKET=/run/skinserve/frames.sock \
  "$image" >/dev/null 2>"$work/run-server.err" || {
  cat "$work/run-server.err"
  fail "podman run of the server failed"
}

say "waiting for SERVING (the image's HEALTHCHECK: skinserve-cli health)"
start=$(date +%s)
until podman healthcheck run "$name" >/dev/null 2>&1; do
  state=$(podman inspect --format '{{.State.Status}}' "$name" 2>/dev/null || echo gone)
  [ "$state" = running ] || fail "server container is $state before becoming healthy"
  [ $(($(date +%s) - start)) -lt 180 ] || fail "not SERVING after 180 s"
  sleep 1
done
say "healthy after $(($(date +%s) - start)) s:" \
  "$(podman exec "$name" skinserve-cli --target "127.0.0.1:$port" "${client_tls[@]}" health 2>&1 | tr '\n' ' ')"
# The limits came from the cgroup: the server says what it sized itself from.
sizing=$(podman logs "$name" 2>&1 | grep -m1 'compute threads' || true)
echo "  | ${sizing#*] }"
case "$sizing" in
  *"cgroup CPU limit 1)"*"cgroup memory limit 2048 MiB"*) ;;
  *) fail "the server did not size itself from the container's cgroup (--cpus 1 --memory 2g)" ;;
esac
if podman exec "$name" skinserve-cli --target "127.0.0.1:$port" --deadline-seconds 5 backends \
    >"$work/plaintext.txt" 2>&1; then
  fail "a plaintext client was served by the mutual-TLS port"
fi
say "plaintext client refused: $(tail -1 "$work/plaintext.txt")"

# SERVING means every backend was built; an OpenCL backend that failed to build (e.g. an
# unwritable PoCL cache) would still leave the server SERVING, degraded. Not here.
podman exec "$name" skinserve-cli --target "127.0.0.1:$port" "${client_tls[@]}" backends >"$work/backends.txt"
sed 's/^/  /' "$work/backends.txt"
unavailable=$(awk 'NR > 1 && $2 == "no" { print $1 }' "$work/backends.txt" | tr '\n' ' ')
[ -z "$unavailable" ] || fail "backends unavailable in the container: $unavailable"
for id in serial openmp sse sse-openmp simd simd-openmp opencl opencl-zerocopy passthrough; do
  awk -v id="$id" '$1 == id && $2 == "yes" { found = 1 } END { exit !found }' \
    "$work/backends.txt" || fail "backend $id missing or unavailable"
done

# The load client from the image, writing its JSON report into $work.
chmod 0777 "$work"
run_load() {
  podman_run --rm --name "$load_name" --no-healthcheck -v "$work:/out" "${tls_mount[@]}" \
    --entrypoint skinserve-load "$image" \
    --target "127.0.0.1:$port" "${client_tls[@]}" "$@"
}
# The load client as a same-host client: in its own container, sharing the server's tmpfs
# volume (its --shm-dir and socket), nothing else: no host path, no network needed.
run_same_host_load() {
  podman_run --rm --name "$load_name" --no-healthcheck -v "$work:/out" --read-only \
    --mount "type=volume,source=$run_volume,destination=/run/skinserve" \
    --entrypoint skinserve-load "$image" \
    --target unix:/run/skinserve/grpc.sock --shm-dir /run/skinserve "$@"
}

# ---- load on every backend, with correctness checks ------------------------------------
say "load: every backend, ${duration} s each, 2 streams, over mutual TLS, every answer checked" \
  "against the reference"
if ! run_load --backends all --vertices 20000 --streams 2 --warmup 0.5 --duration "$duration" \
    --check-every 1 --json /out/load.json >"$work/load.out" 2>&1; then
  cat "$work/load.out"
  fail "load client reported errors"
fi
sed 's/^/  /' "$work/load.out"
python3 - "$work/load.json" <<'PY' || fail "load report shows problems"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
want = {"serial", "openmp", "sse", "sse-openmp", "simd", "simd-openmp", "opencl", "opencl-zerocopy",
        "passthrough"}
seen = {r["backend"] for r in results}
bad = [r["backend"] for r in results
       if r["errors"] or r["mismatches"] or not r["checked"] or not r["frames"]]
if want - seen: print("not load-tested:", sorted(want - seen))
if bad: print("errors, mismatches or nothing checked:", bad)
print("smoke: every backend answered and checked:",
      ", ".join(f"{r['backend']} {r['checked']}/{r['frames']}" for r in results))
sys.exit(1 if bad or want - seen else 0)
PY

# ---- the same-host data plane across two containers ------------------------------------
say "same host: a second container on the shared tmpfs volume, gRPC over the Unix socket," \
  "frames written into its shared-memory regions, both data planes, every answer checked"
if ! run_same_host_load --backends simd-openmp,opencl --data-planes grpc,shm --vertices 20000 \
    --streams 2 --window 2 --instances 2 --warmup 0.5 --duration "$duration" --check-every 1 \
    --json /out/same-host.json >"$work/same-host.out" 2>&1; then
  cat "$work/same-host.out"
  fail "same-host load client reported errors"
fi
sed 's/^/  /' "$work/same-host.out"
python3 - "$work/same-host.json" <<'PY' || fail "same-host report shows problems"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
shm = [r for r in results if r["data_plane"] == "shm"]
bad = [r["backend"] for r in results
       if r["errors"] or r["mismatches"] or not r["checked"] or not r["frames"]]
if len(shm) != 2: print("expected 2 shared-memory rows, got", len(shm))
if bad: print("errors, mismatches or nothing checked:", bad)
print("smoke: same host, shared memory:",
      ", ".join(f"{r['backend']} {r['checked']}/{r['frames']}" for r in shm))
sys.exit(1 if bad or len(shm) != 2 else 0)
PY
# The frame socket from the other container (another pid namespace: its regions are its
# uid's), the same frames without gRPC, every answer checked.
say "same host: the frame socket from the second container, frames into its regions"
if ! run_same_host_load --backends simd-openmp --data-planes socket \
    --frame-socket /run/skinserve/frames.sock --vertices 20000 --streams 2 --rate 30 \
    --warmup 0.5 --duration "$duration" --check-every 1 --json /out/socket.json \
    >"$work/socket.out" 2>&1; then
  cat "$work/socket.out"
  fail "frame-socket load client reported errors"
fi
sed 's/^/  /' "$work/socket.out"
python3 - "$work/socket.json" <<'PY' || fail "frame-socket report shows problems"
import json, sys
rows = json.load(open(sys.argv[1]))["results"]
bad = [r for r in rows if r["data_plane"] != "socket" or r["errors"] or r["mismatches"]
       or not r["checked"] or not r["frames"]]
print("smoke: frame socket:", ", ".join(f"{r['backend']} {r['checked']}/{r['frames']}" for r in rows))
sys.exit(1 if bad or not rows else 0)
PY
# Every client's regions: `regions` lists the asking process's own (none), `stats` counts all.
regions=$(podman exec "$name" skinserve-cli --target unix:/run/skinserve/grpc.sock stats |
  grep '^shared-memory regions')
echo "  $regions"
case "$regions" in "shared-memory regions 0 "*) ;; *) fail "regions left registered after the client ended" ;; esac

# ---- SIGTERM during a load run: drain and exit 0 ---------------------------------------
say "SIGTERM during a load run (sse, 2 streams): the server must drain and exit 0"
run_load --backends sse --vertices 20000 --streams 2 --warmup 0 --duration 8 \
  --check-every 1 --json /out/drain.json >"$work/drain.out" 2>&1 &
load_pid=$!
sleep 3
start=$(date +%s)
podman kill --signal TERM "$name" >/dev/null
code=$(timeout $((drain + 30)) podman wait "$name") ||
  fail "server did not exit within $((drain + 30)) s of SIGTERM"
elapsed=$(($(date +%s) - start))
podman logs "$name" >"$work/server.log" 2>&1
tail -4 "$work/server.log" | sed 's/^/  | /'
[ "$code" = 0 ] || fail "server exited $code after SIGTERM"
grep -q draining "$work/server.log" || fail "server log shows no drain"
say "server drained and exited 0, ${elapsed} s after SIGTERM (drain limit ${drain} s)"

# The load client sees its streams end (UNAVAILABLE: shutting down) and nothing to
# reconnect to. What it did get back must be right. Its run lasts 8 s; give it 30 more.
load_rc=0
for _ in $(seq 1 30); do kill -0 "$load_pid" 2>/dev/null || break; sleep 1; done
if kill -0 "$load_pid" 2>/dev/null; then
  podman rm -f -t 0 "$load_name" >/dev/null 2>&1 || true
  wait "$load_pid" 2>/dev/null || true
  # Not this test's subject (the server drained and exited 0), but worth shouting about.
  say "WARNING: skinserve-load did not finish within 30 s of its run's end after its only" \
    "server stopped: it hangs instead of reporting the remaining frames failed"
else
  wait "$load_pid" || load_rc=$?
  sed 's/^/  /' "$work/drain.out" | grep -v '^  wrote' || true
  python3 - "$work/drain.json" "$load_rc" <<'PY' || fail "answers around the drain"
import json, sys
r = json.load(open(sys.argv[1]))["results"][0]
others = set(r["errors"]) - {"UNAVAILABLE", "CANCELLED"}
print(f"smoke: around SIGTERM: {r['frames']} frames answered, {r['checked']} checked, "
      f"{r['mismatches']} wrong; errors {r['errors']} (load client exit {sys.argv[2]})")
sys.exit(1 if r["mismatches"] or others or not r["frames"] else 0)
PY
fi
say "PASSED"
