#!/usr/bin/env bash
# Installs what is missing, then configures and builds skinserve (Release) into
# ${SKINSERVE_BUILD_DIR:-build}. Shared by test.sh and demo.sh.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
bash "$root/scripts/install-deps.sh"
# ccache, when a developer has it, makes rebuilds in several worktrees cheap; CI needs none.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
cmake --build "$build" -j "$(nproc)"
