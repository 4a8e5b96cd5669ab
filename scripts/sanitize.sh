#!/usr/bin/env bash
# Sanitizer and fuzzing runs (clang-14; docs/reliability.md):
#   scripts/sanitize.sh asan [ctest args]  ASan+UBSan build of everything in build-asan (the
#                                          fuzz targets too), then ctest there; without ctest
#                                          args every test but the deploy (containers) and
#                                          arm64 (cross-built) labels
#   scripts/sanitize.sh asan-ci            what CI runs of it (its time budget): the engine,
#                                          backends, service, security, stress (hostile clients,
#                                          uploads, truncated regions), client, wire, glTF
#                                          importer and fuzz corpora
#   scripts/sanitize.sh tsan               TSan build of the engine's tests in build-tsan, run
#                                          with OpenMP's TSan support (libarcher)
#   scripts/sanitize.sh fuzz [SECONDS]     each libFuzzer target of build-asan for SECONDS
#                                          (default 25), from its seed corpus
# Reports fail the run (halt_on_error); the suppressions in tests/sanitizers/ cover only
# third-party frames, each with its reason.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
mode=${1:?usage: sanitize.sh asan|tsan|fuzz [args]}
shift
bash "$root/scripts/install-deps.sh"
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
# -O2 keeps the tests' big frames fast enough; -g1 gives reports file:line at little cost.
configure() {
  cmake -S "$root" -B "$1" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" \
    -DSKINSERVE_WERROR=OFF "${launcher[@]}" "${@:2}" >/dev/null
}
supp="$root/tests/sanitizers"
# alloc_dealloc_mismatch=0: PoCL compiles OpenCL programs with Debian's LLVM 15, which
# allocates with operator new and frees with free() inside libclang-cpp whenever PoCL's kernel
# cache is cold (a fresh machine, as in CI); ASan 14 cannot suppress that check by library,
# so it is off (new/delete pairs in our code are checked by the other reports only).
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1:alloc_dealloc_mismatch=0"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"

case "$mode" in
  asan | asan-ci)
    build="$root/build-asan"
    configure "$build" -DSKINSERVE_SANITIZE=address,undefined -DSKINSERVE_FUZZ=ON
    if [ "$mode" = asan-ci ]; then
      cmake --build "$build" -j "$(nproc)" --target skinserve skinserve_engine_tests \
        skinserve_backend_tests skinserve_service_tests skinserve_character_tests \
        skinserve_security_tests skinserve_stress_tests skinserve_client_tests \
        skinserve_wire_tests skinserve_frame_socket_tests mesh_upload_fuzzer skin_request_fuzzer \
        gltf_fuzzer raw_part_fuzzer
      set -- -R '^(skinserve_(engine|backend|service|character|security|stress|client|wire|frame_socket)_tests|.*_fuzzer\.corpus)$'
    else
      cmake --build "$build" -j "$(nproc)"
      # Not the container tests (deploy) nor the arm64 cross-build (arm64: another compiler,
      # run under qemu; nothing of this build's instrumentation reaches it).
      if [ $# -eq 0 ]; then set -- -LE '^(deploy|arm64)$'; fi
    fi
    cd "$build"
    ctest --output-on-failure --timeout 1800 "$@"
    ;;
  tsan)
    build="$root/build-tsan"
    configure "$build" -DSKINSERVE_SANITIZE=thread
    cmake --build "$build" -j "$(nproc)" --target skinserve_engine_tests skinserve_backend_tests
    # libarcher tells TSan about libomp's barriers and tasks: without it every OpenMP
    # parallel loop reports false races (libomp itself is not instrumented).
    export OMP_TOOL_LIBRARIES="$(llvm-config-14 --libdir)/libarcher.so" ARCHER_OPTIONS="verbose=1"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:ignore_noninstrumented_modules=1:suppressions=$supp/tsan.supp"
    # The engine (compute pool, mesh store, scheduler) and every CPU backend; the OpenCL
    # backends' threads are PoCL's, which TSan cannot see into.
    "$build/tests/engine/skinserve_engine_tests" --gtest_brief=1
    "$build/tests/backends/skinserve_backend_tests" --gtest_brief=1 --gtest_filter='-*opencl*:*OpenCL*'
    ;;
  fuzz)
    seconds=${1:-25}
    build="$root/build-asan"
    [ -x "$build/tests/fuzz/mesh_upload_fuzzer" ] || {
      echo "build-asan has no fuzz targets: run scripts/sanitize.sh asan first" >&2
      exit 1
    }
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
    for target in mesh_upload_fuzzer skin_request_fuzzer gltf_fuzzer raw_part_fuzzer; do
      mkdir -p "$work/$target"
      echo "== $target: ${seconds}s"
      # New inputs go to the scratch folder (first); the repository's corpus is only read.
      # A crash leaves crash-<sha1> in the current folder: add it to the corpus with its fix.
      if ! "$build/tests/fuzz/$target" -max_total_time="$seconds" -timeout=10 \
        -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$root/" \
        "$work/$target" "$root/tests/fuzz/corpus/$target" 2>"$work/$target.log"; then
        tail -n 60 "$work/$target.log"
        echo "$target failed: its input is in $root/crash-* (or leak-*/timeout-*)" >&2
        exit 1
      fi
      grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done" "$work/$target.log" || true
    done
    ;;
  *)
    echo "usage: sanitize.sh asan|tsan|fuzz [args]" >&2
    exit 2
    ;;
esac
