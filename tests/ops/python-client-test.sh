#!/usr/bin/env bash
# The Python client as a user installs it: a virtual environment on Debian's python3 that
# sees Debian's grpcio, protobuf and numpy (--system-site-packages), `pip install` of
# client/python (stubs generated from proto/ by grpc_tools.protoc during the build; no
# package index), then its pytest suite against a real server.
# usage: python-client-test.sh SKINSERVE REPOSITORY-ROOT WORK-DIR
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 skinserve repository-root work-dir" >&2
  exit 2
fi
server=$(realpath "$1") root=$(realpath "$2") work=$3
python=/usr/bin/python3  # Debian's: its dist-packages hold python3-grpcio and python3-numpy
for module in venv grpc grpc_tools numpy pytest setuptools; do
  "$python" -c "import $module" 2>/dev/null ||
    { echo "python-client-test: SKIPPED: $python lacks $module (scripts/install-deps.sh)"; exit 77; }
done
rm -rf "$work" && mkdir -p "$work"
# Build from a copy, so the checkout stays clean (pip builds in the source folder).
cp -r "$root/client/python" "$work/src"
rm -rf "$work/src/build" "$work/src"/src/*.egg-info
"$python" -m venv --system-site-packages "$work/venv"
SKINSERVE_PROTO_DIR="$root/proto" "$work/venv/bin/pip" install --quiet --no-build-isolation \
  --no-index --disable-pip-version-check "$work/src"
# From the tests' folder, not the source tree: `import skinserve` must find the installed
# package (with its generated skinserve/v1 stubs).
cd "$work/src/tests"
"$work/venv/bin/python" -c 'import skinserve, skinserve.v1.skinning_pb2_grpc; print("installed", skinserve.__file__)'
SKINSERVE_BINARY="$server" SKINSERVE_SOURCE_DIR="$root" exec "$work/venv/bin/python" -m pytest -q -p no:cacheprovider .
