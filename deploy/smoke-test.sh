#!/usr/bin/env bash
# Smoke test of the container image, for real, with podman:
#   1. builds deploy/Dockerfile (making the local Debian base image first when missing),
#   2. starts the server container (detached, host network, on a free loopback port),
#   3. waits for SERVING through the image's own HEALTHCHECK (grpc.health.v1),
#   4. runs the image's load client against it on every backend with correctness checks,
#   5. sends SIGTERM during a load run and checks the server drains and exits 0.
# The container is always removed, whatever happens.
#
# Exits 77 (ctest's skip code) with the reason when podman, runc or debootstrap are
# missing and cannot be installed (not root), when podman cannot run a container here,
# or when SKINSERVE_SKIP_DEPLOY_SMOKE=1.
#
# Env: SKINSERVE_IMAGE (default skinserve:<project version>),
#      SKINSERVE_SMOKE_NO_BUILD=1 (use the existing image, do not build),
#      SKINSERVE_SMOKE_DURATION (load per backend, default 2s).
# usage: deploy/smoke-test.sh
set -euo pipefail

SKIP=77
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
version=$(sed -n 's/^project(skinserve VERSION \([0-9.]*\).*/\1/p' "$root/CMakeLists.txt")
image="${SKINSERVE_IMAGE:-skinserve:$version}"
duration="${SKINSERVE_SMOKE_DURATION:-2s}"
name="skinserve-smoke-$$"
load_name="skinserve-smoke-load-$$"
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-smoke.XXXXXX")

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
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

podman info >"$work/podman-info.txt" 2>&1 || {
  tail -5 "$work/podman-info.txt"
  skip "podman does not work here (podman info failed)"
}

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
  say "building $image from deploy/Dockerfile (compiles the three binaries; ~10 min on 2 cores)"
  start=$(date +%s)
  if ! podman build --pull=never --isolation chroot --network host --format docker \
      --build-arg VERSION="$version" -f "$root/deploy/Dockerfile" -t "$image" "$root" \
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

# ---- run -------------------------------------------------------------------------------
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
say "starting $name on 127.0.0.1:$port (read-only root, as in k8s/deployment.yaml)"
podman_run -d --name "$name" \
  --read-only --tmpfs /tmp:rw,exec,mode=1777 --tmpfs /var/cache/pocl:rw,exec,mode=1777 \
  -e SKINSERVE_LISTEN="127.0.0.1:$port" "$image" >/dev/null

say "waiting for SERVING (the image's HEALTHCHECK: skinserve-cli health)"
start=$(date +%s)
until podman healthcheck run "$name" >/dev/null 2>&1; do
  state=$(podman inspect --format '{{.State.Status}}' "$name" 2>/dev/null || echo gone)
  [ "$state" = running ] || fail "server container is $state before becoming healthy"
  [ $(($(date +%s) - start)) -lt 180 ] || fail "not SERVING after 180 s"
  sleep 1
done
say "healthy after $(($(date +%s) - start)) s:" \
  "$(podman exec "$name" skinserve-cli --target "127.0.0.1:$port" health 2>&1 | tr '\n' ' ')"

# ---- load on every backend, with correctness checks ------------------------------------
say "load: every backend, $duration each, every frame checked against the reference"
if ! podman_run --rm --name "$load_name" --entrypoint skinserve-load "$image" \
    --target "127.0.0.1:$port" --backends all --streams 2 --duration "$duration" \
    --check-every 1 --json >"$work/load.json" 2>"$work/load.err"; then
  cat "$work/load.err" "$work/load.json" | tail -40
  fail "load client reported errors"
fi
python3 - "$work/load.json" <<'EOF' || fail "load report shows problems"
import json, sys
report = json.load(open(sys.argv[1]))
print(json.dumps(report, indent=1)[:3000])
EOF

# ---- SIGTERM: drain and exit 0 ----------------------------------------------------------
say "SIGTERM: server must drain and exit 0"
start=$(date +%s)
podman kill --signal TERM "$name" >/dev/null
code=$(timeout 120 podman wait "$name") || fail "server did not exit within 120 s of SIGTERM"
podman logs "$name" 2>&1 | tail -8 | sed 's/^/  | /'
[ "$code" = 0 ] || fail "server exited $code after SIGTERM"
say "server drained and exited 0 in $(($(date +%s) - start)) s"
say "PASSED"
