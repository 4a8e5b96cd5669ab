#!/usr/bin/env bash
# Lints deploy/: yamllint on the Kubernetes manifests and compose.yaml, then
# check_manifests.py on every kustomize overlay as `kubectl kustomize` renders it (offline)
# for what must agree across them (versions, no thread counts beside the CPU limit, gRPC
# probes, grace period vs drain, selectors, each overlay's TLS, placement and GPU).
# Exit 77 (ctest's skip code) when yamllint or kubectl is missing and cannot be installed
# here (Debian: yamllint, kubernetes-client).
# The budgets of each overlay are checked by the server binary itself (--memory-envelope).
# usage: lint-deploy.sh [repository root [skinserve binary]]
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "${1:-$here/../..}" && pwd)
server="${2:-$root/build/bin/skinserve}"
if [ ! -x "$server" ]; then
  echo "lint-deploy: no skinserve binary at $server (build first, or pass it as the second argument)" >&2
  exit 1
fi

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

# kubectl renders the overlays: Debian's kubernetes-client (1.20, kustomize v2.0.3) or newer.
if [ -z "${KUBECTL:-}" ] && ! command -v kubectl >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "lint-deploy: installing kubectl (Debian package kubernetes-client)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -qq --no-install-recommends kubernetes-client >/dev/null 2>&1 ||
      { apt-get update -qq && apt-get install -y -qq --no-install-recommends kubernetes-client >/dev/null; }
  else
    echo "lint-deploy: SKIPPED: kubectl is not installed and this is not root" \
      "(apt-get install kubernetes-client)"
    exit 77
  fi
fi
echo "lint-deploy: $("${KUBECTL:-kubectl}" version --client 2>/dev/null | head -1)"

cd "$root"
echo "lint-deploy: yamllint -c deploy/.yamllint deploy/"
yamllint --strict -c deploy/.yamllint deploy/
echo "lint-deploy: yamllint ok"
python3 "$here/check_manifests.py" "$root" "$server"
