#!/usr/bin/env bash
# The Python client as a user installs it: a wheel built from client/python (its protobuf
# messages and .pyi stubs generated from proto/ by the system protoc; no package index),
# installed into a fresh virtual environment on Debian's python3 that sees Debian's grpcio,
# protobuf and numpy (--system-site-packages; pip checks the wheel's pinned ranges against
# them), `mypy --strict` on the wheel's files and the examples, then the pytest suite
# (blocking and asyncio clients, the examples, the packaging checks) against a real server,
# importing skinserve from the virtual environment.
# usage: python-client-test.sh SKINSERVE REPOSITORY-ROOT WORK-DIR
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 skinserve repository-root work-dir" >&2
  exit 2
fi
server=$(realpath "$1") root=$(realpath "$2") work=$3
python=/usr/bin/python3  # Debian's: its dist-packages hold python3-grpcio, -protobuf, -numpy
for module in venv grpc google.protobuf numpy pytest setuptools wheel packaging mypy; do
  "$python" -c "import $module" 2>/dev/null ||
    { echo "python-client-test: SKIPPED: $python lacks $module (scripts/install-deps.sh)"; exit 77; }
done
command -v protoc >/dev/null ||
  { echo "python-client-test: SKIPPED: no protoc (protobuf-compiler)"; exit 77; }
rm -rf "$work" && mkdir -p "$work"
# Build from a copy, so the checkout stays clean (setuptools builds in the source folder).
cp -r "$root/client/python" "$work/src"
rm -rf "$work/src/build" "$work/src"/src/*.egg-info "$work/src/dist"
echo "== wheel (system protoc: $(protoc --version))"
SKINSERVE_PROTO_DIR="$root/proto" "$python" -m pip wheel --quiet --no-deps --no-build-isolation \
  --no-index --disable-pip-version-check -w "$work/dist" "$work/src"
wheel=$(ls "$work"/dist/skinserve-*.whl)
echo "built $wheel"
echo "== fresh virtual environment, the wheel installed (dependencies from Debian's packages)"
"$python" -m venv --system-site-packages "$work/venv"
"$work/venv/bin/pip" install --quiet --no-index --disable-pip-version-check "$wheel"
# pip check, for this package only (some of Debian's own packages fail it, not ours).
if "$work/venv/bin/pip" check --disable-pip-version-check | grep -i '^skinserve'; then
  echo "python-client-test: the wheel's requirements are not met by the installed packages"
  exit 1
fi
echo "== mypy --strict on the wheel's files and the examples"
mkdir "$work/unpacked" && (cd "$work/unpacked" && "$python" -m zipfile -e "$wheel" .)
(cd "$work/unpacked" && cp "$work/src/examples"/*.py . &&
  "$python" -m mypy --strict --no-incremental --config-file "$work/src/pyproject.toml" \
    skinserve blocking_client.py asyncio_client.py morph_client.py)
echo "== pytest against a real server, skinserve imported from the virtual environment"
# From the tests' folder, not the source tree: `import skinserve` must find the installed
# package (with its generated skinserve/v1 stubs).
cd "$work/src/tests"
"$work/venv/bin/python" -c 'import skinserve, skinserve.v1.skinning_pb2; print("installed", skinserve.__file__)'
SKINSERVE_BINARY="$server" SKINSERVE_SOURCE_DIR="$root" exec "$work/venv/bin/python" -m pytest -q -p no:cacheprovider .
