#!/usr/bin/env bash
# The documentation site (mkdocs.yml, docs/): fails when a table of a page differs from the
# raw results it is generated from (scripts/docs-tables.py --check), when MkDocs warns
# (a broken link, a missing page: --strict), when a page is missing from the navigation,
# or when a link names an anchor its page does not have. The site goes to
# ${SKINSERVE_BUILD_DIR:-build}/site.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="${SKINSERVE_BUILD_DIR:-$root/build}"
mkdir -p "$build"
build=$(cd "$build" && pwd)
if ! command -v mkdocs >/dev/null; then
  echo "docs: mkdocs is not installed (scripts/install-deps.sh installs mkdocs and mkdocs-material)" >&2
  exit 1
fi
python3 "$root/scripts/docs-tables.py" --check
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
(cd "$root" && mkdocs build --strict --clean -f mkdocs.yml -d "$build/site") >"$log" 2>&1 || status=$?
if [ "$status" -ne 0 ]; then
  cat "$log" >&2
  echo "docs: mkdocs build --strict failed" >&2
  exit 1
fi
# MkDocs 1.4 reports a page left out of the navigation as INFO, not as a warning. A run's
# page (results/<run>/SOURCE.md) stays out of the navigation on purpose: the results index
# lists every run (docs-tables.py --check fails on a run it does not list). MkDocs 1.5 would
# say this with not_in_nav; Debian 12's MkDocs is 1.4, so the check is here.
left_out=$(sed -n '/not included in the "nav" configuration/,/^[A-Z]/p' "$log" |
  grep '^  - ' | grep -Ev '^  - results/[^/]+/SOURCE\.md$' || true)
if [ -n "$left_out" ]; then
  echo "$left_out" >&2
  echo "docs: every page but a run's SOURCE.md must be in mkdocs.yml's nav" >&2
  exit 1
fi
python3 "$root/scripts/docs-tables.py" --check-site "$build/site"
echo "docs: $build/site built"
