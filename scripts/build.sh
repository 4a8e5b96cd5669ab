#!/usr/bin/env bash
# Installs what is missing, then configures and builds skinserve (Release) into
# ${SKINSERVE_BUILD_DIR:-build}. Shared by test.sh and demo.sh.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
bash "$root/scripts/install-deps.sh"
# ccache makes rebuilds in several worktrees cheap, and lets the container image's build
# (deploy/smoke-test.sh mounts this cache into it) reuse what this build just compiled
# (scripts/ccache-launch.sh says how).
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER="$root/scripts/ccache-launch.sh"
            -DCMAKE_CXX_COMPILER_LAUNCHER="$root/scripts/ccache-launch.sh")
fi
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
cmake --build "$build" -j "$(nproc)"
