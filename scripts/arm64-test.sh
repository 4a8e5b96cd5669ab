#!/usr/bin/env bash
# The engine on arm64: cross-builds the engine library and its core and backend tests
# with Debian's aarch64 cross toolchain (scripts/toolchains/aarch64-linux-gnu.cmake, the
# arm64 packages installed multiarch by install-deps.sh) and runs them under qemu-user,
# whose CPU has NEON, SVE and SVE2: the `simd` backends are checked on every target the
# build has, at 128-, 256- and 512-bit SVE vectors (QEMU_CPU). Extra arguments go to ctest.
# ctest runs it as the `arm64` test (label arm64).
#   scripts/arm64-test.sh [-R simd]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_ARM64_BUILD_DIR:-${SKINSERVE_BUILD_DIR:-$root/build}/arm64}"
bash "$root/scripts/install-deps.sh" >/dev/null
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSKINSERVE_ENGINE_ONLY=ON \
  -DCMAKE_TOOLCHAIN_FILE="$root/scripts/toolchains/aarch64-linux-gnu.cmake" "${launcher[@]}" \
  >/dev/null
cmake --build "$build" -j "$(nproc)"
cd "$build"
# Not into test.sh's gtest reports: under qemu no arm64 OpenCL platform is installed, so
# the OpenCL cases skip here by design (PoCL runs them in the x86 suite), and test.sh's
# skip report (CI: every test must run) is about the x86 suite.
unset GTEST_OUTPUT
ctest --output-on-failure --timeout 1200 "$@"
