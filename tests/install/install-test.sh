#!/usr/bin/env bash
# The installed skinserve, end to end:
#   1. `cmake --install BUILD --prefix P`: programs, headers (the generated protobuf ones
#      too), libraries, the CMake package, skinserve-client.pc and man pages in P; no path of
#      the build or source tree in the package files;
#   2. every installed program answers --version with the same version;
#   3. client/examples/external-project, copied out of the tree, configured with
#      CMAKE_PREFIX_PATH=P alone (find_package(skinserve CONFIG)) and built;
#   4. the same main.cpp built by one g++ command with `pkg-config --cflags --libs
#      skinserve-client`;
#   5. both binaries skin a frame on the installed server and check it against their own
#      float64 reference (exit 0 only when every position agrees).
# usage: install-test.sh BUILD-DIR SOURCE-DIR CXX
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"
if [ $# -ne 3 ]; then
  echo "usage: $0 BUILD-DIR SOURCE-DIR CXX" >&2
  exit 2
fi
build=$(cd "$1" && pwd) source_dir=$(cd "$2" && pwd) cxx=$3
work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-install.XXXXXX")
server_pid=
say() { echo "install-test: $*"; }
fail() { echo "install-test: FAILED: $*" >&2; exit 1; }
cleanup() {
  local rc=$?
  if [ -n "$server_pid" ]; then kill -KILL "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  if [ $rc -ne 0 ]; then
    for f in "$work"/*.log; do [ -f "$f" ] && { echo "--- $f"; tail -30 "$f"; }; done
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
prefix=$work/prefix

# ---- 1. the install ------------------------------------------------------------------------
say "cmake --install into $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log" 2>&1 || fail "cmake --install"
for f in bin/skinserve bin/skinserve-cli bin/skinserve-load \
  include/skinserve/client/skin_client.h include/skinserve/client/channel.h \
  include/skinserve/wire/conversions.h include/skinserve/model/status.h \
  include/skinserve/encoding/vertex_encoding.h include/skinserve/v1/skinning.pb.h \
  include/skinserve/v1/skinning.grpc.pb.h include/grpc/health/v1/health.grpc.pb.h \
  share/man/man1/skinserve.1 share/man/man1/skinserve-cli.1 share/man/man1/skinserve-load.1; do
  [ -e "$prefix/$f" ] || fail "$f is not installed"
done
config=$(find "$prefix" -name skinserveConfig.cmake)
pc=$(find "$prefix" -name skinserve-client.pc)
[ -n "$config" ] && [ -f "$(dirname "$config")/skinserveConfigVersion.cmake" ] || fail "no CMake package"
[ -n "$pc" ] || fail "no skinserve-client.pc"
for library in client wire proto encoding model; do
  [ -n "$(find "$prefix" -name "libskinserve_$library.a")" ] || fail "libskinserve_$library.a is not installed"
done
# The package must stand alone: nothing in it may point back at the build or the sources.
if grep -rlF -e "$build" -e "$source_dir" "$(dirname "$config")" "$pc" "$prefix/include"; then
  fail "installed package files name the build or source tree (above)"
fi
grep -q '^\.TH SKINSERVE ' "$prefix/share/man/man1/skinserve.1" || fail "skinserve.1 is no man page"
for page in skinserve skinserve-load; do
  grep -q 'config' "$prefix/share/man/man1/$page.1" || fail "$page.1 does not document --config"
done

# ---- 2. --version ----------------------------------------------------------------------------
want=$(sed -n 's/^project(skinserve VERSION \([0-9.]*\).*/\1/p' "$source_dir/CMakeLists.txt")
versions=()
for program in skinserve skinserve-cli skinserve-load; do
  line=$("$prefix/bin/$program" --version) || fail "$program --version failed"
  say "$line"
  case "$line" in
    "$program $want"*) versions+=("${line#"$program "}") ;;
    *) fail "$program --version: '$line' is not '$program $want...'" ;;
  esac
done
[ "${versions[0]}" = "${versions[1]}" ] && [ "${versions[0]}" = "${versions[2]}" ] ||
  fail "the programs disagree on the version: ${versions[*]}"

# ---- 3. find_package, outside the tree --------------------------------------------------------
cp -r "$source_dir/client/examples/external-project" "$work/example"
say "configuring and building the example project against the prefix"
cmake -S "$work/example" -B "$work/example-build" -G Ninja -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_PREFIX_PATH="$prefix" >"$work/example-configure.log" 2>&1 || fail "configure (find_package)"
cmake --build "$work/example-build" >"$work/example-build.log" 2>&1 || fail "build (find_package)"

# ---- 4. pkg-config, one command ---------------------------------------------------------------
say "building it with pkg-config"
export PKG_CONFIG_PATH
PKG_CONFIG_PATH=$(dirname "$pc")
# shellcheck disable=SC2046
"$cxx" -std=c++20 -o "$work/skin-one-frame-pc" "$work/example/main.cpp" \
  $(pkg-config --cflags --libs skinserve-client) >"$work/pkg-config-build.log" 2>&1 ||
  fail "g++ with pkg-config --cflags --libs skinserve-client"

# ---- 5. both skin a frame on the installed server --------------------------------------------
"$prefix/bin/skinserve" --listen 127.0.0.1:0 --port-file "$work/port" --threads 1 \
  >"$work/server.log" 2>&1 &
server_pid=$!
port=$(wait_for_port "$work/port" "$server_pid" 60) || fail "installed server not serving"
for binary in "$work/example-build/skin-one-frame" "$work/skin-one-frame-pc"; do
  "$binary" "127.0.0.1:$port" >"$work/run.log" 2>&1 || fail "$(basename "$binary"): $(cat "$work/run.log")"
  say "$(basename "$binary"): $(cat "$work/run.log")"
  grep -q ': OK$' "$work/run.log" || fail "no OK from $binary"
done
kill -TERM "$server_pid"
wait "$server_pid" || fail "the server exited non-zero after SIGTERM"
server_pid=
say "PASSED"
