#!/usr/bin/env bash
# Installs every Debian 12 package skinserve needs to build, test and run.
# Idempotent: packages already present are left alone; needs root (or sudo).
#   install-deps.sh [all]   everything: build, run, tests, plots, deploy tests (the default)
#   install-deps.sh build   what compiling needs (the container's build stage)
#   install-deps.sh runtime what the binaries need to run (the container's runtime stage)
set -euo pipefail

BUILD_PACKAGES=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers
  libglm-dev libcli11-dev libspdlog-dev libfmt-dev
  libtinygltf-dev nlohmann-json3-dev libstb-dev libcairo2-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang-format
)
# What the binaries need at run time (the container's runtime stage uses this list).
RUNTIME_PACKAGES=(
  pocl-opencl-icd ocl-icd-libopencl1 clinfo
  libgrpc++1.51 libprotobuf32 libspdlog1.10 libfmt9 libgomp1 libtinygltf2d libcairo2 libssl3
)
# The interop test (a client nobody here wrote) and the plots.
TEST_PACKAGES=(
  python3 python3-grpcio python3-grpc-tools python3-numpy python3-matplotlib gnuplot-nox
)
# The deployment tests: manifests lint, and the container image built and run with podman
# (deploy/smoke-test.sh).
DEPLOY_PACKAGES=(
  yamllint podman runc debootstrap
)

# Proof under stress: clang with its sanitizer and libFuzzer runtimes, libomp for TSan
# (its libarcher), iproute2 for the network-fault test's namespaces and netem.
STRESS_PACKAGES=(
  clang-14 libclang-rt-14-dev libomp-14-dev iproute2 procps
)

want=("${BUILD_PACKAGES[@]}" "${RUNTIME_PACKAGES[@]}" "${TEST_PACKAGES[@]}" "${DEPLOY_PACKAGES[@]}"
  "${STRESS_PACKAGES[@]}")
case "${1:-all}" in
  runtime) want=("${RUNTIME_PACKAGES[@]}") ;;                      # the container's runtime stage
  build) want=("${BUILD_PACKAGES[@]}" "${RUNTIME_PACKAGES[@]}") ;;  # compile, no test tools
  all) ;;
  *) echo "usage: $0 [all|build|runtime]" >&2; exit 2 ;;
esac

missing=()
for p in "${want[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#want[@]} packages present"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
