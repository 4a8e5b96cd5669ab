#!/usr/bin/env bash
# Lints deploy/: yamllint on the Kubernetes manifests and compose.yaml, then
# check_manifests.py for what must agree across them (versions, CPU vs compute threads,
# gRPC probes, grace period vs drain, selectors).
# Exit 77 (ctest's skip code) when yamllint is missing and cannot be installed here.
# usage: lint-deploy.sh [repository root]
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "${1:-$here/../..}" && pwd)

if ! command -v yamllint >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "lint-deploy: installing yamllint (Debian package)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq --no-install-recommends yamllint >/dev/null 2>&1 ||
      { apt-get update -qq && apt-get install -y -qq --no-install-recommends yamllint >/dev/null; }
  else
    echo "lint-deploy: SKIPPED: yamllint is not installed and this is not root" \
      "(apt-get install yamllint)"
    exit 77
  fi
fi

cd "$root"
echo "lint-deploy: yamllint -c deploy/.yamllint deploy/"
yamllint --strict -c deploy/.yamllint deploy/
echo "lint-deploy: yamllint ok"
python3 "$here/check_manifests.py" "$root"
