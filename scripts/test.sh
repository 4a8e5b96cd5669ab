#!/usr/bin/env bash
# Builds skinserve and runs every test through ctest; exits non-zero on any failure.
# Extra arguments go to ctest (e.g. scripts/test.sh -L core, or -R Engine).
# Afterwards it lists every test that did not run (ctest skips and GTEST_SKIP cases) with
# its reason; with CI=true any such skip fails the run (CI expects every test to run).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
bash "$root/scripts/build.sh"
# The documentation site (docs/): tables match their raw results, mkdocs build --strict.
bash "$root/scripts/docs.sh"
results="$build/test-results"
rm -rf "$results"
mkdir -p "$results/gtest"
cd "$build"
status=0
GTEST_OUTPUT="xml:$results/gtest/" \
  ctest --output-on-failure --timeout 900 --output-junit "$results/ctest.xml" "$@" || status=$?
skips=()
if [ "${CI:-}" = true ]; then skips=(--fail); fi
python3 "$root/scripts/report-skips.py" "$results" "${skips[@]}" || status=1
exit "$status"
