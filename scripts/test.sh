#!/usr/bin/env bash
# Builds skinserve and runs every test through ctest; exits non-zero on any failure.
# Extra arguments go to ctest (e.g. scripts/test.sh -L core, or -R Engine).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
bash "$root/scripts/build.sh"
cd "$build"
ctest --output-on-failure --timeout 900 "$@"
